import sys

from navsim.cli import main

sys.exit(main())
