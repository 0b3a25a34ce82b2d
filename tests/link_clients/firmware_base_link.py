# The real firmware offering link version 1 only, as a firmware built before version 2
# (tests/test_link_reads.py): the host must serve it as before, byte for byte.
import sys

from firmware import main
from protocol import sim_link

sim_link.VERSIONS = (sim_link.VERSION,)
sys.exit(main.start())
