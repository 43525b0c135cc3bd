"""What the tests, the demo and the benchmarks share: real ROS processes and probes, the fake robot's
launch sequences, waits with deadlines, and snapsim systems (tools/setup-env installs it into .venv).

- ros_harness: a roscore per test module, processes from the install spaces, RosProbe
- rosprobe: the rospy side of RosProbe (run as a child process)
- processes: the demo's long-running processes (roscore, simulator, fake robot)
- real_robot, nav_launch, roscore_restart: launch sequences of the robot, navigation, a master restart
- pty_session: a program on a pseudo-terminal, as a person at a terminal
- snap_system: a snapsim root driven like `snap`
- waiting: wait_until
"""
