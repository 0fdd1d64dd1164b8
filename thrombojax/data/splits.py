"""Train / validation / test split by simulation (never by frame), as in the study.

Default: one test and two validation simulations, drawn by a seeded permutation of the names in
natural order (so the split does not depend on the order the names are given in); the rest
train. :func:`make_split` fixes the sets by name instead (e.g. test on the 190 deg rotation).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from thrombojax.errors import ConfigError
from thrombojax.io.schema import natural_key

__all__ = ["Split", "split_simulations", "make_split"]


@dataclasses.dataclass(frozen=True)
class Split:
    """Simulation names of each part (disjoint tuples, natural order within each)."""

    train: tuple[str, ...]
    val: tuple[str, ...]
    test: tuple[str, ...]

    def to_dict(self) -> dict[str, list[str]]:
        return {"train": list(self.train), "val": list(self.val), "test": list(self.test)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Split:
        try:
            return cls(*(tuple(str(n) for n in d[k]) for k in ("train", "val", "test")))
        except (KeyError, TypeError) as err:
            msg = f"split: expected keys train/val/test with name lists, got {d!r}"
            raise ConfigError(msg) from err


def _unique(names: Sequence[str]) -> list[str]:
    names = [str(n) for n in names]
    if len(set(names)) != len(names):
        dupes = sorted({n for n in names if names.count(n) > 1})
        raise ConfigError(f"split: duplicate simulation names {dupes}")
    return sorted(names, key=natural_key)


def split_simulations(
    names: Sequence[str], *, n_test: int = 1, n_val: int = 2, seed: int = 0
) -> Split:
    """Split simulations at random (seeded) into train / val / test.

    Args:
        names: simulation names (unique).
        n_test: number of test simulations (>= 0).
        n_val: number of validation simulations (>= 0).
        seed: seed of the permutation.
    Returns:
        The :class:`Split`; at least one simulation trains.
    Raises:
        ConfigError: negative counts, duplicates, or no simulation left to train on.
    """
    ordered = _unique(names)
    if n_test < 0 or n_val < 0:
        raise ConfigError(f"split: n_test={n_test} and n_val={n_val} must be >= 0")
    if n_test + n_val >= len(ordered):
        raise ConfigError(
            f"split: {len(ordered)} simulations cannot give {n_test} test + {n_val} validation "
            "and still leave one to train on; lower --n-val / --n-test or add simulations"
        )
    perm = np.random.default_rng(seed).permutation(len(ordered))
    picked = [ordered[i] for i in perm]
    test, val, train = picked[:n_test], picked[n_test : n_test + n_val], picked[n_test + n_val :]
    return Split(*(tuple(sorted(p, key=natural_key)) for p in (train, val, test)))


def make_split(
    names: Sequence[str],
    *,
    test: Sequence[str],
    val: Sequence[str] = (),
    train: Sequence[str] | None = None,
) -> Split:
    """A split fixed by name; ``train`` defaults to every name not in test or val.

    Raises:
        ConfigError: an unknown name, a name in two parts, or an empty training set.
    """
    known = _unique(names)
    parts = {"test": list(test), "val": list(val)}
    parts["train"] = (
        [n for n in known if n not in set(parts["test"]) | set(parts["val"])]
        if train is None
        else list(train)
    )
    seen: dict[str, str] = {}
    for part, members in parts.items():
        for n in members:
            if n not in known:
                raise ConfigError(f"split: unknown simulation {n!r} in {part} (have {known})")
            if n in seen:
                raise ConfigError(f"split: simulation {n!r} is in both {seen[n]} and {part}")
            seen[n] = part
    if not parts["train"]:
        raise ConfigError("split: no simulation left to train on")
    return Split(
        *(tuple(sorted(parts[k], key=natural_key)) for k in ("train", "val", "test"))
    )
