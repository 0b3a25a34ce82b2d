"""The two papers' reproductions, above the toolkit: seed 003's tactile hexapod (the
experiment, the GRNN, the error model) and seed 000's beam traversal (estimator, landscape,
planner, the force-sensing experiment). The toolkit never imports them; importing this
package plugs their features into it (host_tools/plugins.py): ``hexhil run`` of a beams
scenario, ``--navigator model|grnn``."""
from hexhil.papers import beam_traversal, tactile_hexapod

__all__ = ["beam_traversal", "tactile_hexapod"]
