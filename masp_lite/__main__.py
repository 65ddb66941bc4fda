"""``python -m masp_lite COMMAND ...`` (see :mod:`masp_lite.cli`)."""
import sys

from masp_lite.cli import main

if __name__ == "__main__":
    sys.exit(main())
