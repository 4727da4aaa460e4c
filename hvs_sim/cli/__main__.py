"""`python -m hvs_sim.cli`: the `hvs-sim` command."""

import sys

from hvs_sim.cli import main

if __name__ == "__main__":
    sys.exit(main())
