"""TurtleBot3 robot models: the numbers every other package needs.

`models` gives each model's wheel geometry, velocity limits and footprint, so
the driver, the teleoperation nodes, the simulator and the planner agree.
"""
