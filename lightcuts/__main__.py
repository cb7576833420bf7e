import sys

from lightcuts.cli import main

if __name__ == "__main__":  # not when a Dask worker process started by --workers imports the main module
    sys.exit(main())
