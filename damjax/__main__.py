import sys

from damjax.cli import main

sys.exit(main())
