"""Dense 3D face sequences from the ICT FaceKit linear model, for tests and benchmarks.

A face is ``neutral + identity @ identity_deltas + weights(t) @ expression_deltas`` (ICT FaceKit, units cm). The
expression weights vary smoothly in time: talking (jaw and mouth shapes), smiles, blinks, brow raises. Frame 0 is
the neutral face of the identity (all weights 0). Vertex ``i`` is the same point of the face in every frame and
every identity, which gives exact ground truth for tracking and transfer.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..io.obj import open_npz

_KEYS = ("neutral", "identity_deltas", "expression_deltas", "expression_names", "landmark68_vertex_idx")


@dataclass(frozen=True)
class FaceModel:
    """The linear face model. neutral : (n_vertices, 3) float32; identity_deltas : (n_id, n_vertices, 3);
    expression_deltas : (n_expr, n_vertices, 3); expression_names : tuple of str; landmark68 : (68,) int64;
    quads : (n_quads, 4) int64 (may be empty)."""

    neutral: np.ndarray
    identity_deltas: np.ndarray
    expression_deltas: np.ndarray
    expression_names: tuple
    landmark68: np.ndarray
    quads: np.ndarray


@dataclass(frozen=True)
class FaceSequence:
    """frames : (n_frames, n_vertices, 3) float32 (frame 0 neutral); weights : (n_frames, n_expr) float64;
    identity : (n_id,) float64 coefficients; landmark68 : (68,) int64 vertex indices."""

    frames: np.ndarray
    weights: np.ndarray
    identity: np.ndarray
    landmark68: np.ndarray


def load_face_model(path: str | Path) -> FaceModel:
    """Read the ICT FaceKit ``.npz`` (see ../shared/data/README.md). Raises InputError naming what is missing."""
    path = Path(path)
    with open_npz(path, "face model") as data:
        missing = [k for k in _KEYS if k not in data.files]
        if missing:
            raise InputError(f"{path}: face model lacks {', '.join(missing)}")
        quads = data["quads"].astype(np.int64) if "quads" in data.files else np.zeros((0, 4), np.int64)
        return FaceModel(
            neutral=data["neutral"].astype(np.float32),
            identity_deltas=data["identity_deltas"].astype(np.float32),
            expression_deltas=data["expression_deltas"].astype(np.float32),
            expression_names=tuple(str(s) for s in data["expression_names"]),
            landmark68=data["landmark68_vertex_idx"].astype(np.int64),
            quads=quads,
        )


def random_identity(model: FaceModel, rng: np.random.Generator, *, n_components: int = 40) -> np.ndarray:
    """Identity coefficients: standard normal on the first ``n_components`` (the deltas carry the PCA scale)."""
    coefs = np.zeros(len(model.identity_deltas))
    k = min(n_components, len(coefs))
    coefs[:k] = rng.standard_normal(k)
    return coefs


def neutral_face(model: FaceModel, identity: np.ndarray) -> np.ndarray:
    """(n_vertices, 3) float64 neutral face of an identity."""
    return model.neutral + np.tensordot(identity, model.identity_deltas, axes=1).astype(np.float64)


def _bumps(t: np.ndarray, rng: np.random.Generator, *, rate: float, width: float, height: tuple) -> np.ndarray:
    """Sum of smooth bumps (raised cosines) at random times: ``rate`` per frame, ``width`` frames wide."""
    out = np.zeros(len(t))
    n = rng.poisson(rate * len(t)) + 1
    for centre, amp in zip(rng.uniform(0, len(t), n), rng.uniform(*height, n), strict=True):
        u = np.clip((t - centre) / width, -1.0, 1.0)
        out += amp * 0.5 * (1.0 + np.cos(np.pi * u))
    return out


class _Weights:
    """(n_frames, n_expr) expression weights being built: ``add(name, curve)`` (names the model lacks are
    skipped), then ``done()`` fades everything in over the first 8 frames (frame 0 neutral) and clips to [0, 1]."""

    def __init__(self, names: tuple, n_frames: int):
        self.t = np.arange(n_frames, dtype=np.float64)
        self.index = {name: i for i, name in enumerate(names)}
        self.w = np.zeros((n_frames, len(names)))

    def add(self, name: str, curve: np.ndarray) -> None:
        if name in self.index:
            self.w[:, self.index[name]] += curve

    def done(self) -> np.ndarray:
        return np.clip(self.w * np.clip(self.t / 8.0, 0.0, 1.0)[:, None], 0.0, 1.0)


def expression_weights(names: tuple, n_frames: int, rng: np.random.Generator) -> np.ndarray:
    """(n_frames, n_expr) smooth weights in [0, 1]: talking, smiling, blinking, jaw opening, brows; row 0 zero."""
    w = _Weights(names, n_frames)
    t, add = w.t, w.add
    # talking: the jaw and lips follow a syllable rhythm (~4 Hz at 25 fps) under a slowly varying envelope
    envelope = np.clip(_bumps(t, rng, rate=0.02, width=30, height=(0.5, 1.0)), 0, 1)
    phase = rng.uniform(0, 2 * np.pi, 4)
    syllable = 0.5 * (1 - np.cos(2 * np.pi * t / 6.0 + phase[0]))
    add("jawOpen", 0.45 * envelope * syllable)
    add("mouthFunnel", 0.3 * envelope * np.clip(np.sin(2 * np.pi * t / 17.0 + phase[1]), 0, 1))
    add("mouthPucker", 0.3 * envelope * np.clip(np.sin(2 * np.pi * t / 23.0 + phase[2]), 0, 1))
    add("mouthClose", 0.15 * envelope * syllable)
    add("mouthStretch_L", 0.2 * envelope * np.clip(np.sin(2 * np.pi * t / 13.0 + phase[3]), 0, 1))
    add("mouthStretch_R", 0.2 * envelope * np.clip(np.sin(2 * np.pi * t / 13.0 + phase[3]), 0, 1))
    # a wide jaw opening now and then
    add("jawOpen", _bumps(t, rng, rate=0.008, width=12, height=(0.3, 0.5)))
    # smiles (slightly asymmetric) with cheek squint
    smile = _bumps(t, rng, rate=0.01, width=25, height=(0.5, 0.9))
    asym = rng.uniform(0.8, 1.0)
    add("mouthSmile_L", smile)
    add("mouthSmile_R", asym * smile)
    add("cheekSquint_L", 0.5 * smile)
    add("cheekSquint_R", 0.5 * asym * smile)
    # blinks: short, both eyes
    blink = _bumps(t, rng, rate=0.03, width=3, height=(0.9, 1.0))
    add("eyeBlink_L", blink)
    add("eyeBlink_R", blink)
    # brows
    brow = _bumps(t, rng, rate=0.01, width=15, height=(0.4, 0.8))
    add("browInnerUp_L", brow)
    add("browInnerUp_R", brow)
    add("browOuterUp_L", 0.6 * brow)
    add("browOuterUp_R", 0.6 * brow)
    return w.done()


def make_sequence(
    model: FaceModel, *, n_frames: int = 101, identity: np.ndarray | None = None, seed: int = 0
) -> FaceSequence:
    """A sequence F^0..F^{n_frames-1} of one identity (random from ``seed`` unless given); frame 0 neutral."""
    if n_frames < 1:
        raise ValueError(f"n_frames must be >= 1, got {n_frames}")
    rng = np.random.default_rng(seed)
    if identity is None:
        identity = random_identity(model, rng)
    weights = expression_weights(model.expression_names, n_frames, rng)
    return FaceSequence(apply_weights(model, identity, weights), weights, np.asarray(identity, np.float64),
                        model.landmark68)


def apply_weights(model: FaceModel, identity: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(n_frames, n_vertices, 3) float32 faces of ``identity`` with the given expression weights (ground truth)."""
    frames = neutral_face(model, identity)[None] + np.tensordot(weights, model.expression_deltas, axes=1)
    return frames.astype(np.float32)


def blind_spot_weights(names: tuple, n_frames: int, rng: np.random.Generator) -> np.ndarray:
    """(n_frames, n_expr) smooth weights of motions the 68 landmarks see badly: cheek puffs, nose sneers, a pucker
    and a jaw opening, each as a few smooth bumps of moderate strength; row 0 zero."""
    w = _Weights(names, n_frames)
    t, add = w.t, w.add
    rate = 3.0 / max(n_frames, 1)  # about three of each per sequence, whatever its length
    puff = _bumps(t, rng, rate=rate, width=15, height=(0.3, 0.7))
    add("cheekPuff_L", puff)
    add("cheekPuff_R", rng.uniform(0.7, 1.0) * puff)
    sneer = _bumps(t, rng, rate=rate, width=12, height=(0.3, 0.7))
    add("noseSneer_L", sneer)
    add("noseSneer_R", rng.uniform(0.7, 1.0) * sneer)
    add("mouthPucker", _bumps(t, rng, rate=rate, width=12, height=(0.3, 0.7)))
    add("jawOpen", _bumps(t, rng, rate=rate, width=12, height=(0.05, 0.2)))
    return w.done()


def head_turn(n_frames: int, *, yaw_deg: float = 15.0, pitch_deg: float = 5.0) -> np.ndarray:
    """(n_frames, 3, 3) rotations of a slow head turn: yaw swings to +-``yaw_deg`` and back over the sequence, with
    a smaller nod (``pitch_deg``); frame 0 is the identity."""
    u = np.arange(n_frames) / max(n_frames - 1, 1)
    yaw = np.radians(yaw_deg) * np.sin(2 * np.pi * u)
    pitch = np.radians(pitch_deg) * np.sin(np.pi * u) ** 2
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    one, zero = np.ones(n_frames), np.zeros(n_frames)
    r_yaw = np.stack([np.stack([cy, zero, sy], 1), np.stack([zero, one, zero], 1), np.stack([-sy, zero, cy], 1)], 1)
    r_pitch = np.stack([np.stack([one, zero, zero], 1), np.stack([zero, cp, -sp], 1), np.stack([zero, sp, cp], 1)], 1)
    return r_yaw @ r_pitch


def make_blind_sequence(
    model: FaceModel, *, n_frames: int = 60, identity: np.ndarray | None = None, seed: int = 0,
    yaw_deg: float = 15.0, pitch_deg: float = 5.0,
) -> FaceSequence:
    """A sequence of :func:`blind_spot_weights` under a slow :func:`head_turn` (about the centroid of the neutral
    face's vertices, i.e. inside the head); frame 0 neutral and unrotated."""
    if n_frames < 1:
        raise ValueError(f"n_frames must be >= 1, got {n_frames}")
    rng = np.random.default_rng(seed)
    if identity is None:
        identity = random_identity(model, rng)
    weights = blind_spot_weights(model.expression_names, n_frames, rng)
    frames = apply_weights(model, identity, weights).astype(np.float64)
    centre = frames[0].mean(0)
    frames = (frames - centre) @ head_turn(n_frames, yaw_deg=yaw_deg, pitch_deg=pitch_deg).transpose(0, 2, 1) + centre
    return FaceSequence(frames.astype(np.float32), weights, np.asarray(identity, np.float64), model.landmark68)


def partial_scans(frames: np.ndarray, vertices: np.ndarray, rng: np.random.Generator, *, fraction: float = 0.6,
                  noise: float = 0.0) -> list:
    """Point clouds as a scanner gives them: per frame a random ``fraction`` of ``vertices`` (indices into the
    frames' vertices, e.g. the face), shuffled, with isotropic Gaussian noise of standard deviation ``noise``."""
    out = []
    for f in frames:
        pick = rng.choice(vertices, int(round(fraction * len(vertices))), replace=False)
        out.append(f[pick].astype(np.float64) + noise * rng.standard_normal((len(pick), 3)))
    return out
