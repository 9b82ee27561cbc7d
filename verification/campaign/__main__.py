"""`python -m verification.campaign [--quick] [--json] [--out DIR]`, and `--vcan-guest SPECS
OUT` inside the sandbox: the command line of the campaign (verification/campaign/part.py, `main`)."""
import sys

from .part import main

if __name__ == "__main__":
    sys.exit(main())
