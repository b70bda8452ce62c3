"""``python -m pcdcodec.cli``: the same command line as ``python -m pcdcodec``."""

import sys

from . import main

sys.exit(main())
