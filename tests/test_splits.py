"""Splits by simulation: defaults of the study, seeded, disjoint, explicit splits."""

from __future__ import annotations

import pytest

from thrombojax.data.splits import Split, make_split, split_simulations
from thrombojax.errors import ConfigError

NAMES = [f"rot_{d:03d}" for d in range(0, 200, 10)]  # BendVessel: 20 rotations


def test_defaults_one_test_two_val_rest_train():
    s = split_simulations(NAMES)
    assert (len(s.train), len(s.val), len(s.test)) == (17, 2, 1)
    assert sorted(s.train + s.val + s.test) == sorted(NAMES)
    assert len(set(s.train) | set(s.val) | set(s.test)) == 20


def test_seeded_and_order_independent():
    a = split_simulations(NAMES, seed=3)
    assert a == split_simulations(list(reversed(NAMES)), seed=3)
    seeds = {split_simulations(NAMES, seed=k).test for k in range(10)}
    assert len(seeds) > 3  # different seeds pick different test simulations
    c = split_simulations(NAMES, n_test=2, n_val=0, seed=1)
    assert (len(c.train), len(c.val), len(c.test)) == (18, 0, 2)
    assert Split.from_dict(a.to_dict()) == a


def test_explicit_split():
    s = make_split(NAMES, test=["rot_190"], val=["rot_000", "rot_100"])
    assert s.test == ("rot_190",) and s.val == ("rot_000", "rot_100") and len(s.train) == 17
    t = make_split(NAMES, test=["rot_190"], train=["rot_010", "rot_020"])
    assert t.train == ("rot_010", "rot_020") and t.val == ()


@pytest.mark.parametrize(
    "call",
    [
        lambda: split_simulations(NAMES[:3], n_test=1, n_val=2),
        lambda: split_simulations(NAMES, n_test=-1),
        lambda: split_simulations(["a", "a", "b", "c", "d"]),
        lambda: make_split(NAMES, test=["nope"]),
        lambda: make_split(NAMES, test=["rot_190"], val=["rot_190"]),
        lambda: make_split(NAMES[:2], test=["rot_000"], val=["rot_010"]),
        lambda: Split.from_dict({"train": []}),
    ],
)
def test_errors(call):
    with pytest.raises(ConfigError):
        call()
