"""The demo's options; read before anything else is imported, so that --help needs nothing built."""
import argparse
import os
import tempfile

from . import explorer

MODELS = ("burger", "waffle", "waffle_pi")


def parse_args(argv):
    parser = argparse.ArgumentParser(
        prog="demo/run",
        description="turtlebot3c end to end, headless: install the snap (through snapsim by default), "
                    "map a simulated world while driving around it, save the map, navigate to goals on it. "
                    "Prints progress and a summary; writes OUT/map_with_driven_path.png, "
                    "OUT/navigation_paths.png and OUT/summary.json.")
    parser.add_argument("--real-robot", action="store_true",
                        help="simulation=false: the snap's drivers talk to the fake OpenCR board and LIDAR")
    parser.add_argument("--quick", action="store_true", help="a short tour and one goal (for the tests)")
    parser.add_argument("--model", default="waffle_pi", choices=MODELS, help="turtlebot3-model (default waffle_pi)")
    parser.add_argument("--lds-model", default="LDS-01", choices=("LDS-01", "LDS-02"), help="with --real-robot")
    parser.add_argument("--world", default="turtlebot3_world", choices=sorted(explorer.TOURS))
    parser.add_argument("--speed", type=float, default=0.18, help="the explorer's top speed, m/s (default 0.18)")
    parser.add_argument("--turn-rate", type=float,
                        help="the explorer's top turn rate, rad/s (default 0.8; on the real-robot path too: "
                             "SLAM, AMCL and the costmaps deskew the LIDAR's 0.2 s revolutions)")
    parser.add_argument("--snap-cli", default="snapsim", choices=("snapsim", "snap"),
                        help="snapsim (a private root, default) or the real snap (as root, with --snap-file)")
    parser.add_argument("--snap-file", help="the .snap to install with --snap-cli snap")
    parser.add_argument("--out", default=os.path.join(tempfile.gettempdir(), "turtlebot3c-demo"),
                        help="folder for the pictures, the summary and the logs (default: %(default)s)")
    parser.add_argument("--summary-json", help="also write the summary (OUT/summary.json) here")
    parser.add_argument("--no-setup", action="store_true", help="(demo/run) skip setup-env and build")
    parser.add_argument("--ros-setup", action="append", metavar="FILE",
                        help="(demo/run) source FILE instead of the build's install spaces (repeatable)")
    return parser.parse_args(argv)
