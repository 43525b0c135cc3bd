"""python3 -m demo [options]: the end-to-end demo (see demo/run)."""
import sys

from demo.options import parse_args

options = parse_args(sys.argv[1:])  # --help ends here, before the demo's imports need a built workspace
from demo.demo import Demo  # noqa: E402

sys.exit(Demo(options).run())
