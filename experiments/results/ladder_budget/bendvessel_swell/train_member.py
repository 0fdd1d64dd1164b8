"""Train member SEED of a ladder rung into the folder the ladder's own ``_member_runs`` uses
(``OUT/<reused rung>/member_<seed>``), beside a ladder process that trains another member; a
later ladder run finds it trained and evaluates it. Run from the repository root::

    python experiments/results/ladder_budget/bendvessel_swell/train_member.py \
        axis_swell10_last_seeds3 /work/ladder/bv_swell10 2 data/bendvessel.h5
"""

import dataclasses
import json
import pathlib
import sys

sys.path.insert(0, "experiments")
import ladder  # noqa: E402


def main() -> None:
    rung_name, out, seed, data = sys.argv[1], pathlib.Path(sys.argv[2]), int(sys.argv[3]), \
        sys.argv[4]
    rung = next(r for r in ladder.RUNGS if r.name == rung_name)
    first = out / rung.reuse / "run"
    epochs = json.loads((first / "config.json").read_text())["train"]["epochs"]
    folder = ladder._member_folder(rung, out, seed)
    folder.mkdir(parents=True, exist_ok=True)
    print("training", folder, epochs, "epochs", flush=True)
    member = dataclasses.replace(rung, name=f"{rung.name} member {seed}",
                                 train={**rung.train, "seed": seed})
    split = {"test_sims": ["bendvessel_005", "bendvessel_012", "bendvessel_019"],
             "val_sims": ["bendvessel_009"]}  # the ladder's defaults
    ladder._train_rung(member, data, folder, split, 0.0, epochs, epochs, None, ladder.COMMON)
    print("done", flush=True)


if __name__ == "__main__":
    main()
