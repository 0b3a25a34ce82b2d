# The real firmware, built for a link version this host does not speak
# (tests/test_link_errors.py): the host must refuse its hello.
import sys

from firmware import main
from protocol import sim_link

sim_link.VERSIONS = (max(sim_link.VERSIONS) + 1,)
sys.exit(main.start())
