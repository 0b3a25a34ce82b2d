"""The fork server's trace, held in memory instead of written: an execution is judged from
its messages, never from a file.

Installed on the server's recorder before the boot, ``HeldTrace`` keeps each chunk the
recorder would write (its encoded messages, in order) and records nothing on the topics no
expectation of the case reads (the servo line's bytes, the link, telemetry, the 3D scene).
At the fork the server decodes the boot's messages once; each forked child decodes only
its own at the end and judges the two together (host_tools/expect/verdicts.py ``judged``).
The reproducer of a finding is run fresh and recorded whole (execution.py ``fresh``).
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Callable

from mcap.records import Schema

from hexhil.expect.spec import Case
from hexhil.expect.verdicts import Recording, reads, topics_read
from hexhil.trace import topics
from hexhil.trace.channels import topic_schema
from hexhil.trace.reader import message_decoder
from hexhil.trace.windows import Encoded, EncodeIn

# the recorder's methods for topics an expectation seldom reads: left out unless one does
# (``can`` writes /can/raw and the frame's /can/NAME: read together)
SKIPPED = (("serial", topics.T_SERIAL), ("serial_stream", topics.T_SERIAL),
           ("link", topics.T_LINK), ("telemetry", topics.T_TELEMETRY),
           ("can", topics.T_CAN_RAW))
SCENE = (topics.T_SCENE, topics.T_SCENE_FRAMES, topics.T_SCENE_FORCES)


def _nothing(*_: Any) -> None:
    """A recorder method for a topic nobody reads."""


class HeldTrace:
    """A run's recorder keeping its chunks in memory (``chunks``) for ``case`` to judge."""

    def __init__(self, run: Any, case: Case) -> None:
        self.rec = run.recorder
        if self.rec.encode_in is not EncodeIn.THIS_PROCESS:
            raise RuntimeError("a held trace needs its recorder to encode in this process")
        self.wanted = topics_read(case)
        self.chunks: list[Encoded] = []
        self.boot: dict[str, list[tuple[float, dict[str, Any]]]] = {}
        self._decoders: dict[int, Callable[[bytes], Any]] = {}
        self.rec._write_chunk = self._keep
        for method, topic in SKIPPED:
            if not reads(topic, self.wanted):
                setattr(self.rec, method, _nothing)
        if not self.wanted.intersection(SCENE):
            run.sim.core.truth.scene = False

    def _keep(self, msgs: Encoded, _packing: Any = None) -> None:
        self.chunks.append(msgs)

    def at_fork(self) -> None:
        """In the server, at the fork: what the boot recorded, decoded once."""
        self.rec.flush()
        self.boot = self._decoded()
        self.chunks = []

    def in_child(self) -> None:
        """In a forked child: the file it shares with the server gets nothing more (the
        MCAP summary its run writes at the end goes nowhere), and is renamed nowhere."""
        fd = os.open(os.devnull, os.O_WRONLY)
        os.dup2(fd, self.rec._file.fileno())
        os.close(fd)
        self.rec._target.partial = None

    def recording(self, summary: dict[str, Any]) -> Recording:
        """The boot's messages and the child's, as ``verdicts.read`` gives a trace's."""
        messages = {t: list(v) for t, v in self.boot.items()}
        for topic, values in self._decoded().items():
            messages.setdefault(topic, []).extend(values)
        return Recording(float(summary.get("sim_time_s", 0.0)), summary, messages)

    def _decoded(self) -> dict[str, list[tuple[float, dict[str, Any]]]]:
        names = {cid: topic for topic, cid in self.rec._channels.ids.items()}
        out: dict[str, list[tuple[float, dict[str, Any]]]] = {}
        for chunk in self.chunks:
            for t_ns, cid, data in chunk:
                topic = names[cid]
                if not reads(topic, self.wanted):
                    continue
                out.setdefault(topic, []).append((t_ns / 1e9, self._decoder(cid, topic)(data)))
        return out

    def _decoder(self, cid: int, topic: str) -> Callable[[bytes], Any]:
        dec = self._decoders.get(cid)
        if dec is None:
            name, encoding = topics.CHANNELS.get(topic, (topic, "json"))   # /can/*: json
            schema = (Schema(id=0, name=name, encoding="protobuf", data=topic_schema(topic))
                      if encoding == "protobuf" else None)
            dec = self._decoders[cid] = message_decoder(encoding, schema, Path("held trace"))
        return dec
