"""Train one ladder model into a folder of its own and measure it alone (how this folder's new
models were made, two at a time), with the ladder's own ``_train_rung`` and ``_evaluate``.

Usage: ``python train_one.py BASE NAME SEED '{"option": value}' DATA OUT_ROOT``; ``BASE`` is a
recipe of ``experiments/ladder_rungs.py``. The ``nohist`` seeds (``SIGNED``, the default recipe
with wall noise and signed wall features, plus the options given; no history noise)::

    python train_one.py SIGNED dnspR_s1 1 '{"speed_noise": 0.1, "direction_noise": 0.1,
        "select_by": "rollout"}' data/bendvessel.h5 runs

and the default recipe's seeds (``WALK``)::

    python train_one.py WALK walkR_s0 0 '{"select_by": "rollout"}' data/bendvessel.h5 runs
"""

import json
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[4]))  # experiments/
import ladder  # noqa: E402
import ladder_rungs  # noqa: E402

SPLIT = {"test_sims": ["bendvessel_005", "bendvessel_012", "bendvessel_019"],
         "val_sims": ["bendvessel_009"]}


def main() -> None:
    base, name, seed, extra, data, root = sys.argv[1:7]
    folder = pathlib.Path(root) / name
    folder.mkdir(parents=True, exist_ok=True)
    rung = ladder.Rung(name, {**getattr(ladder_rungs, base), "seed": int(seed),
                              **json.loads(extra)})
    run = ladder._train_rung(rung, data, folder, SPLIT, 0.0, 25, 25, None)
    res = ladder._evaluate([run], data, False)
    (folder / "result.json").write_text(json.dumps(res, indent=1))
    print(json.dumps(res["mean"], indent=1))


if __name__ == "__main__":
    main()
