"""``python -m hexhil.bus_fuzz.server IN OUT``: one of the fuzzer's server processes
(host_tools/bus_fuzz/fork_server.py ``Server`` starts it): a target, then inputs, on the
pipe IN; a verdict each on OUT."""
import sys

from hexhil.bus_fuzz.fork_server import server_main

if __name__ == "__main__":
    server_main(sys.argv[1:3])
