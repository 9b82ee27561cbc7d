"""`python -m verification.mutation [--target python|c] [--files ...] [--scope ...] [--json] [--list] ...`: the
command line of the mutation tool (verification/mutation/tool.py, `main`)."""
import sys

from .tool import main

if __name__ == "__main__":
    sys.exit(main())
