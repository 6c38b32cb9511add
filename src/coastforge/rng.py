"""One root seed; every stage (and every object inside a stage) derives its own generator.

``stage_rng(seed, "terrain")`` always gives the same stream for the same seed and name, independent
of the order in which stages run, so adding a stage never changes another stage's randomness.
"""

from __future__ import annotations

import zlib

import numpy as np


def _key(name: str) -> int:
    return zlib.crc32(name.encode("utf-8"))


def stage_rng(seed: int, *names: str | int) -> np.random.Generator:
    """A generator for ``names`` (e.g. ``"synth", "boats", 3``) derived from the root ``seed``."""
    keys = [_key(str(n)) for n in names]
    return np.random.default_rng(np.random.SeedSequence(entropy=int(seed), spawn_key=tuple(keys)))


def stage_seed(seed: int, *names: str | int) -> int:
    """A 32-bit integer seed for libraries that want an int (OpenCV, FAISS, sklearn)."""
    return int(stage_rng(seed, *names).integers(0, 2**31 - 1))
