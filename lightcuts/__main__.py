import sys

from lightcuts.cli import main

sys.exit(main())
