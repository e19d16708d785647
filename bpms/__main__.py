"""``python -m bpms`` runs the command line."""

import sys

from bpms.cli import main

sys.exit(main())
