"""The GRNN of seed 003 Sec. 2.6 and Fig. 8, its file format, and the one-walk predictor.

Per step t the input is the previous per-leg error (6) and the step's onboard sensing
(``features.SENSING``), normalised; a Linear + ReLU embeds it into 64 dimensions ("a
transformation using rectified linear unit embeds the input into a 64-dimensional
vector"), one ``LSTMCell(64, 64)`` ("a single LSTM cell ... hidden state size of 64")
carries the walk, and a Linear(64 -> 6) gives the error of each leg after step t. Over the
known path X the previous error is the measured one; over the future path P the model's
own output is fed back (Fig. 8, dashed feedback connection).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from hexhil.extras import require

require("torch")   # before torch itself: a missing extra is one line, not a traceback
import torch  # noqa: E402

from hexhil.papers.tactile_hexapod.grnn.features import FEATURE_VERSION, LEGS, SENSING
from hexhil.protocol.errors import BadFile, BadValue

HIDDEN = 64        # Sec. 2.6: hidden state size 64
EMBED = 64         # Sec. 2.6: ReLU embedding into 64 dimensions
FORMAT = "hexhil-grnn-1"


@dataclass
class Norm:
    """Input normalisation from the training set: sensing columns and per-leg errors (m)."""

    sensing_mean: list[float]
    sensing_std: list[float]
    error_mean_m: list[float]
    error_std_m: list[float]


class GRNN(torch.nn.Module):
    """Fig. 8: embedding + LSTM cell + per-leg output, rolled out with feedback."""

    def __init__(self, n_sensing: int = len(SENSING)) -> None:
        super().__init__()
        self.embed = torch.nn.Linear(LEGS + n_sensing, EMBED)
        self.cell = torch.nn.LSTMCell(EMBED, HIDDEN)
        self.head = torch.nn.Linear(HIDDEN, LEGS)

    def step(self, x: torch.Tensor, state: tuple[torch.Tensor, torch.Tensor]
             ) -> tuple[torch.Tensor, tuple[torch.Tensor, torch.Tensor]]:
        """One step: x = [prev error, sensing] (normalised), (h, c) -> (error, (h, c))."""
        h, c = self.cell(torch.relu(self.embed(x)), state)
        return self.head(h), (h, c)

    def forward(self, sensing: torch.Tensor, error: torch.Tensor, n_known: torch.Tensor,
                error0: torch.Tensor) -> torch.Tensor:
        """Roll out a batch (all normalised). ``sensing`` (B, T, S), ``error`` (B, T, 6)
        the measured errors, ``n_known`` (B,) steps of the known path, ``error0`` (6,) a
        zero error normalised. Returns the predicted errors (B, T, 6); padding past a
        sequence's end never reaches its earlier steps."""
        b, t_len, _ = sensing.shape
        state = (sensing.new_zeros(b, HIDDEN), sensing.new_zeros(b, HIDDEN))
        prev = error0.expand(b, LEGS)
        out = []
        for t in range(t_len):
            y, state = self.step(torch.cat([prev, sensing[:, t]], dim=1), state)
            out.append(y)
            known = (t < n_known).unsqueeze(1)
            prev = torch.where(known, error[:, t], y)
        return torch.stack(out, dim=1)


class Predictor:
    """One walk at a time for the navigator: lists in, lists out, no autograd."""

    def __init__(self, model: GRNN, norm: Norm, meta: dict[str, Any]) -> None:
        self.model = model.eval()
        self.norm = norm
        self.meta = meta
        self._s_mean = np.asarray(norm.sensing_mean, dtype=np.float32)
        self._s_std = np.asarray(norm.sensing_std, dtype=np.float32)
        self._e_mean = np.asarray(norm.error_mean_m, dtype=np.float32)
        self._e_std = np.asarray(norm.error_std_m, dtype=np.float32)
        self._x_np = np.zeros((1, LEGS + len(SENSING)), dtype=np.float32)
        self._x = torch.from_numpy(self._x_np)   # shares memory with _x_np: no copy a step
        self.reset()

    def reset(self) -> None:
        """Start of a walk: previous error zero, LSTM state zero."""
        self._x_np[0, :LEGS] = -self._e_mean / self._e_std
        self._state = (torch.zeros(1, HIDDEN), torch.zeros(1, HIDDEN))

    def step(self, sensing: Sequence[float], known_error_m: Sequence[float] | None = None
             ) -> list[float]:
        """One completed step: the predicted error per leg (m) after it. A given
        ``known_error_m`` (known path) becomes the next previous error; otherwise the
        prediction is fed back."""
        self._x_np[0, LEGS:] = (np.asarray(sensing, dtype=np.float32) - self._s_mean) / self._s_std
        with torch.inference_mode():
            y, self._state = self.model.step(self._x, self._state)
        y_np = y.numpy()[0]
        if known_error_m is None:
            self._x_np[0, :LEGS] = y_np
        else:
            self._x_np[0, :LEGS] = (np.asarray(known_error_m, dtype=np.float32)
                                    - self._e_mean) / self._e_std
        return (y_np * self._e_std + self._e_mean).tolist()


def save(path: str | Path, model: GRNN, norm: Norm, meta: dict[str, Any]) -> None:
    """The state dict, the normalisation, the dataset's metadata and the feature
    definition it was trained on, in one torch file."""
    try:
        torch.save({"format": FORMAT, "feature_version": FEATURE_VERSION,
                    "sensing": list(SENSING), "state_dict": model.state_dict(),
                    "norm": asdict(norm), "meta": meta}, str(path))
    except (OSError, RuntimeError) as exc:   # torch reports a missing folder as RuntimeError
        raise BadFile(f"{path}: cannot write the model ({type(exc).__name__})") from None


def load(path: str | Path) -> Predictor:
    """A model file written by ``save``; one-line ``UserError`` for anything else or for
    a model whose features differ from this code's."""
    p = Path(path)
    if not p.is_file():
        raise BadFile(f"{p}: no such model file")
    try:
        blob = torch.load(str(p), map_location="cpu", weights_only=True)
    except Exception as exc:   # torch raises many kinds for a file that is not its own
        raise BadValue(f"{p}: not a GRNN model file ({type(exc).__name__})") from None
    if not isinstance(blob, dict) or blob.get("format") != FORMAT:
        raise BadValue(f"{p}: not a GRNN model file")
    if blob.get("feature_version") != FEATURE_VERSION or tuple(blob.get("sensing", ())) != SENSING:
        raise BadValue(f"{p}: model features {blob.get('feature_version')!r} "
                       f"({len(blob.get('sensing', ()))} sensing columns) do not match this "
                       f"code's {FEATURE_VERSION!r} ({len(SENSING)}); retrain it")
    model = GRNN()
    try:
        model.load_state_dict(blob["state_dict"])
        norm = Norm(**blob["norm"])
    except (RuntimeError, TypeError, KeyError) as exc:
        raise BadValue(f"{p}: damaged GRNN model file ({type(exc).__name__})") from None
    return Predictor(model, norm, blob["meta"])

