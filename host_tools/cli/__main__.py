"""``python -m host_tools.cli``: the same entry point as the ``hexhil`` script."""
import sys

from host_tools.cli import main

sys.exit(main())
