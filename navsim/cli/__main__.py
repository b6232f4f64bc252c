"""``python -m navsim.cli``: the ``navsim`` command."""

import sys

from navsim.cli.entry import main

sys.exit(main())
