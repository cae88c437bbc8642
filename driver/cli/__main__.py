"""``python -m driver.cli``: the ``rayflex`` command line."""

import sys

from . import main

sys.exit(main())
