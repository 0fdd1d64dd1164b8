"""Train seed SEED of a ladder rung for EPOCHS epochs on a chosen split into the folder the
ladder evaluates it from (``OUT/<rung>/run`` for seed 0, ``OUT/<rung>/member_<seed>/run``
otherwise), without evaluating it. Run from the repository root::

    python experiments/results/ladder_budget/clotentry_finetune/train_rung.py \\
        follow_nohist_cm_last /work/exp/ce_ft 0 data/clotentry.h5 4 \\
        --test clotentry_008,clotentry_009 --val clotentry_007 --nodes 2048
"""

import argparse
import pathlib
import sys

sys.path.insert(0, "experiments")
import ladder  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("rung")
    p.add_argument("out", type=pathlib.Path)
    p.add_argument("seed", type=int)
    p.add_argument("data")
    p.add_argument("epochs", type=int)
    p.add_argument("--test", required=True, help="held-out simulations, comma-separated")
    p.add_argument("--val", required=True, help="validation simulations, comma-separated")
    p.add_argument("--nodes", type=int, default=None, help="nodes per sample (ladder's --nodes)")
    a = p.parse_args()
    split = {"test_sims": a.test.split(","), "val_sims": a.val.split(",")}
    print("done:", ladder.train_seed(a.rung, a.out, a.seed, a.data, a.epochs, split, a.nodes),
          flush=True)


if __name__ == "__main__":
    main()
