"""``python -m thrombojax`` runs the command-line interface."""

import sys

from thrombojax.cli import main

sys.exit(main())
