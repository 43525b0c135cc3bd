"""python3 -m e2e [options]: the end-to-end demo (see scripts/demo)."""
import sys

from e2e.demo import main

sys.exit(main())
