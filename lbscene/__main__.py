import sys

from lbscene.cli import main

sys.exit(main())
