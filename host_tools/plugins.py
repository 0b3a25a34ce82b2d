"""Where the papers' reproductions (host_tools/papers/) plug into the toolkit, so the toolkit
never imports them: the host side of a world that steps itself (seed 000's beams: push,
sense, estimate, plan) and the navigators of ``hexhil run --navigator``. A package plugs in
as pytest's and python-can's plug-ins do: it names a module in the ``hexhil.plugins`` entry
point group (pyproject.toml ``[project.entry-points]``), and the module registers its
plug-ins here when it is imported. The group is loaded the first time a plug-in is asked
for, so a script's ``Run`` of a beams scenario needs no import of its own (docs/api.md)."""
from __future__ import annotations

from importlib.metadata import entry_points
from typing import Any, Callable, Mapping, Protocol

from hexhil.hil.run_result import RunResult
from hexhil.hil.scenario import Scenario, WorldKind
from hexhil.hil.seams import CanGateway, CanHub, FirmwareWorld, HostNode, TraceRecorder
from hexhil.protocol.errors import BadFile, BadValue, UserError


class SteppedRun(Protocol):
    """A whole run of a world that steps itself, with its host nodes (seed 000's traversal)."""

    def __call__(self, scenario: Scenario, seed: int, recorder: TraceRecorder | None,
                 can_server: CanGateway | None, scene: bool, realtime: bool) -> RunResult: ...


class Navigator(HostNode, Protocol):
    """A host node that stops the walk where it predicts the goal is reached."""

    distance_m: float

    def summary(self) -> Mapping[str, Any]: ...


class RunWithNodes(Protocol):
    """What a navigator attaches to (host_tools/lockstep_run.py ``Run``)."""

    world: FirmwareWorld | None

    @property
    def can(self) -> CanHub: ...
    def add_node(self, node: HostNode) -> None: ...


# (scenario, model file or None) -> what attaches the navigator to a run; its options are
# checked (and a model file loaded) when it is called, before any run opens.
NavigatorPlan = Callable[[Scenario, "str | None"], Callable[[RunWithNodes], Navigator]]

GROUP = "hexhil.plugins"
_STEPPED_LOADERS: dict[WorldKind, Callable[[], SteppedRun]] = {}
_NAVIGATORS: dict[str, NavigatorPlan] = {}
_discovered = False


def discover() -> None:
    """Import every module of the ``hexhil.plugins`` entry point group once (each registers
    its plug-ins); a module that fails to import is one line naming it, not a traceback."""
    global _discovered
    if _discovered:
        return
    _discovered = True
    for ep in entry_points(group=GROUP):
        try:
            ep.load()
        except ImportError as exc:
            raise UserError(f"plug-in {ep.name} ({ep.value}) cannot be imported: {exc}") from exc


def register_stepped_run(kind: WorldKind, load: Callable[[], SteppedRun]) -> None:
    """``load`` imports the run's machinery and returns it: called when a run of ``kind`` is
    made, before its trace opens, so a Ctrl-C in a slow import never meets an open trace."""
    _STEPPED_LOADERS[kind] = load


def stepped_run(kind: WorldKind) -> SteppedRun:
    """The run registered for a world of ``kind``, loaded."""
    discover()
    try:
        load = _STEPPED_LOADERS[kind]
    except KeyError:
        raise BadFile(f"no installed plug-in runs a {kind.value} world (entry point group "
                      f"{GROUP}: is hexhil installed?)") from None
    return load()


def register_navigator(name: str, plan: NavigatorPlan) -> None:
    _NAVIGATORS[name] = plan


def navigator_plan(name: str) -> NavigatorPlan:
    """The navigator registered as ``name``."""
    discover()
    try:
        return _NAVIGATORS[name]
    except KeyError:
        known = ", ".join(sorted(_NAVIGATORS)) or f"none installed (entry point group {GROUP})"
        raise BadValue(f"navigator {name!r}: known ones are {known}") from None
