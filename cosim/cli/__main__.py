"""``python -m cosim.cli``: the ``cosim`` command."""

import sys

from cosim.cli.main import main

sys.exit(main())
