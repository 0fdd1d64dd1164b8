"""Train seed SEED of a ladder rung for EPOCHS epochs into the folder the ladder evaluates it from
(``OUT/<rung>/run`` for seed 0, ``OUT/<rung>/member_<seed>/run`` otherwise), so several seeds can
train side by side before one ladder command evaluates them all. Held out: the ladder's default
simulations ``PREFIX_005``, ``_012``, ``_019``, validation ``PREFIX_009``; PREFIX is the
optional sixth argument (default ``bendvessel``). Run from the repository root::

    python experiments/results/ladder_budget/bendvessel_swell5/train_seed.py \
        axis_swell10 /work/exp/bv_swell10 3 data/bendvessel.h5 25
    python experiments/results/ladder_budget/bendvessel_swell5/train_seed.py \
        axis_swell10 /work/exp/bv_shapes 0 data/bendvessel_shapes.h5 25 bendvessel-shapes
"""

import pathlib
import sys

sys.path.insert(0, "experiments")
import ladder  # noqa: E402


def main() -> None:
    rung_name, out, seed = sys.argv[1], pathlib.Path(sys.argv[2]), int(sys.argv[3])
    data, epochs = sys.argv[4], int(sys.argv[5])
    prefix = sys.argv[6] if len(sys.argv) > 6 else "bendvessel"
    split = {k: [n.replace("bendvessel", prefix, 1) for n in names]  # the ladder's defaults
             for k, names in (("test_sims", ladder.DEFAULT_TEST), ("val_sims", ladder.DEFAULT_VAL))}
    print("done:", ladder.train_seed(rung_name, out, seed, data, epochs, split), flush=True)


if __name__ == "__main__":
    main()
