import sys

from neck_sim.cli import main

sys.exit(main())
