"""``python -m hexhil.cli``: the same entry point as the ``hexhil`` script."""
import sys

from hexhil.cli import main

sys.exit(main())
