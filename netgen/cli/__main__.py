"""`python -m netgen.cli`: the console command, signal handlers first (netgen.cli.main)."""

import sys

from . import main

sys.exit(main())
