"""`python3 -m snapsim`: the snapsim command line (tools/setup-env installs it as .venv/bin/snapsim).

Usage: snapsim --root DIR <install|remove|set|get|unset|start|stop|restart|services|logs|
                           connections|connect|disconnect|run|lint> ...
"""
import sys

from snapsim.cli import main

sys.exit(main())
