"""``python -m damjax.ensemble`` (the same as ``damjax ensemble``)."""

import sys

from damjax.ensemble.cli import main

sys.exit(main())
