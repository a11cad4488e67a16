"""``python -m notchfit``: the ``notchfit`` command line (:func:`notchfit.cli.main`)."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
