"""Thin shim: ``python cli.py ...`` runs the ``notchfit`` command line."""
import sys

from notchfit.cli import main

if __name__ == "__main__":
    sys.exit(main())
