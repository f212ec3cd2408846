"""``python -m lbscene``: the command line (guarded, so that importing this module runs nothing)."""

import sys

from lbscene.cli import main

if __name__ == "__main__":
    sys.exit(main())
