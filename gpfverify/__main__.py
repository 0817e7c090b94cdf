import sys

from gpfverify.cli import main

sys.exit(main())
