"""The end-to-end demo of turtlebot3c (demo/run): the guide's final test, headless.

Install the snap (through snapsim, or the real `snap`), point it at a simulator
(or the fake OpenCR and LIDAR), map the world while an explorer drives, save and install
the map, navigate to goals on it, then print a summary and draw pictures.

Modules:
- snap_control: the `snap` command line (snapsim in a private root, or the real one)
- explorer: the tour a driver would take, planned on the world, followed with pure pursuit
- ros_link: the demo's own ROS node (ground truth, tf, key_vel, move_base action)
- pictures: PNGs of the map, the driven path and the navigation paths
- demo: the steps, their progress lines and the summary
"""
