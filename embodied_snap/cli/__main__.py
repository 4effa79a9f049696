"""`python -m embodied_snap.cli`: the same as `esnap`."""

import sys

from . import main

sys.exit(main())
