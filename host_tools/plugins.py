"""Where the papers' reproductions (host_tools/papers/) plug into the toolkit, so the toolkit
never imports them: the host side of a world that steps itself (seed 000's beams: push,
sense, estimate, plan) and the navigators of ``hexhil run --navigator``. A paper's package
registers its plug-ins when it is imported; the CLI imports ``host_tools.papers`` (all of
them), an API user imports the one they need (docs/api.md)."""
from __future__ import annotations

from typing import Any, Callable, Mapping, Protocol

from hil.run_result import RunResult
from hil.scenario import Scenario, WorldKind
from hil.seams import CanGateway, CanHub, FirmwareWorld, HostNode, TraceRecorder
from protocol.errors import UserError


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

_STEPPED_LOADERS: dict[WorldKind, Callable[[], SteppedRun]] = {}
_NAVIGATORS: dict[str, NavigatorPlan] = {}


def register_stepped_run(kind: WorldKind, load: Callable[[], SteppedRun]) -> None:
    """``load`` imports the run's machinery and returns it: called when a run of ``kind`` is
    made, before its trace opens, so a Ctrl-C in a slow import never meets an open trace."""
    _STEPPED_LOADERS[kind] = load


def stepped_run(kind: WorldKind) -> SteppedRun:
    """The run registered for a world of ``kind``, loaded."""
    try:
        load = _STEPPED_LOADERS[kind]
    except KeyError:
        raise UserError(f"a {kind.value} world is run by its paper's package: import "
                        "host_tools.papers (hexhil does) to plug it in") from None
    return load()


def register_navigator(name: str, plan: NavigatorPlan) -> None:
    _NAVIGATORS[name] = plan


def navigator_plan(name: str) -> NavigatorPlan:
    """The navigator registered as ``name``."""
    try:
        return _NAVIGATORS[name]
    except KeyError:
        known = ", ".join(sorted(_NAVIGATORS)) or "none registered: import host_tools.papers"
        raise UserError(f"navigator {name!r}: known ones are {known}") from None
