"""``python -m turbinefit.cli``: the ``turbinefit`` command."""

import sys

from turbinefit.cli import main

sys.exit(main())
