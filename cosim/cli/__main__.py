import sys

from cosim.cli.main import main

sys.exit(main())
