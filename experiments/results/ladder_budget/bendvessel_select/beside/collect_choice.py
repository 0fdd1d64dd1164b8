"""Per seed: the checkpoint each rule keeps and its held-out rollout (the model alone).

Usage: ``python collect_choice.py RUNS_FOLDER OUT.json > OUT.md``. ``RUNS_FOLDER`` holds each
run as ``NAME/run`` with its rule's checkpoint measured in ``NAME/result.json`` and its last
checkpoint in ``NAME_last/result.json`` (both the stability ladder's ``_evaluate``).
"""

import json
import pathlib
import sys

DIRSPEED = "+ direction and speed noise 0.1"
NOHIST = "direction and speed noise 0.1, no history noise"
RUNS = [  # (recipe label, seed, run name, code)
    ("history noise", 0, "hn_s0", "earlier"), ("history noise", 1, "hn_s1", "earlier"),
    ("+ speed noise 0.1", 0, "sp10_s0", "earlier"),
    ("+ direction noise 0.1", 0, "dn_s0", "earlier"),
    (DIRSPEED, 0, "dnsp_s0", "earlier"), (DIRSPEED, 1, "dnsp_s1", "earlier"),
    (DIRSPEED, 2, "dnsp_s2", "earlier"),
    (NOHIST, 0, "dnspR_s0", "current"), (NOHIST, 1, "dnspR_s1", "current"),
    (NOHIST, 2, "dnspR_s2", "current"), (NOHIST, 3, "dnspR_s3", "current"),
]


def summary(path: pathlib.Path) -> dict | None:
    if not path.is_file():
        return None
    m = json.loads(path.read_text())["mean"]
    return {"mse_full_ratio": m["mse_full"] / m["mse_full_cv"],
            "final_centroid_r": m["final_centroid_r"], "max_outside": m["max_outside"],
            "mse1_phase_ratio": m["mse1_phase"] / m["mse1_phase_cv"]}


def row(folder: pathlib.Path, label: str, seed: int, name: str, code: str) -> dict:
    run = folder / name / "run"
    recs = [json.loads(ln) for ln in (run / "metrics.jsonl").read_text().splitlines() if ln]
    config = json.loads((run / "config.json").read_text())
    select_by = config["train"].get("select_by", "mse")
    best = int(sorted((run / "checkpoints" / "best").iterdir())[-1].name)
    mse_epoch = min(recs, key=lambda r: r["val_mse"])["epoch"]
    out = {"recipe": label, "seed": seed, "run": name, "code": code,
           "trained_select_by": select_by, "mse_epoch": mse_epoch,
           "last_epoch": recs[-1]["epoch"], "last": summary(folder / f"{name}_last" /
                                                            "result.json")}
    if select_by == "mse":
        out["mse"] = summary(folder / name / "result.json")
    else:
        out["rollout_epoch"] = best // config["steps_per_epoch"]
        out["rollout"] = summary(folder / name / "result.json")
        at = next(r for r in recs if r["epoch"] == mse_epoch)
        out["val_rollout_cv_ratio_at_mse_epoch"] = at["val_rollout_cv_ratio"]
    return out


def cell(s: dict | None, epoch) -> str:
    if s is None:
        return "-"
    return (f"{s['mse_full_ratio']:.2f}x, {s['final_centroid_r']:.2f} r, "
            f"{100 * s['max_outside']:.0f} % (epoch {epoch})")


def main() -> None:
    folder, out = pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2])
    rows = [row(folder, *r) for r in RUNS]
    out.write_text(json.dumps({"command": "python collect_choice.py " + " ".join(sys.argv[1:]),
                               "rows": rows}, indent=1))
    print("| recipe | seed | code | one-step validation MSE | validation rollout | last epoch |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        mse = cell(r["mse"], r["mse_epoch"]) if "mse" in r else (
            f"not kept (epoch {r['mse_epoch']}; validation rollout "
            f"{r['val_rollout_cv_ratio_at_mse_epoch']:.2f}x there)")
        rollout = cell(r["rollout"], r["rollout_epoch"]) if "rollout" in r else "-"
        print(f"| {r['recipe']} | {r['seed']} | {r['code']} | {mse} | {rollout} | "
              f"{cell(r['last'], r['last_epoch'])} |")


if __name__ == "__main__":
    main()
