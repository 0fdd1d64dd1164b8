"""Write ``ce_small18/table.md``, ``ladder.json`` and ``error_per_step.png`` from the device's
``result.json``. run2.sh's time limit stopped ``experiments/ladder.py`` after it had saved the
rung's result (06:56:48 UTC) and before it scored the members alone and wrote the report; the
checkpoints stayed on the device, so the members alone cannot be scored here. The environment
is the device's (run.sh's ``ce_small/ladder.json``: the same device kind, image and versions),
with run2.sh's command and time; the load was not recorded. The members alone are not
scored, so the table has no ``Seeds:`` line.

    python experiments/results/ladder_gpu/fifth_session/report18.py
"""
import json
import pathlib
import sys

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[2]))  # experiments/
from ladder_report import write_reports  # noqa: E402

out = HERE / "ce_small18"
name = "follow_nohist_cm_last_ens3_guards"
results = {name: json.loads((out / name / "result.json").read_text())}
env = {**json.loads((HERE / "ce_small" / "ladder.json").read_text())["environment"],
       "date": "2026-11-27T06:56:48+00:00", "load_avg_1_5_15": "not recorded",
       "command": "ladder.py --dataset /root/d/clotentry.h5 --nodes 2048 --test "
                  "clotentry_008,clotentry_009 --val clotentry_007 --epochs 18 --out "
                  "/root/d/ce_small18 --rungs follow_nohist_cm_last_ens3_guards (run2.sh; the "
                  "report written afterwards by report18.py on a CPU machine)"}
write_reports(out, results, title="ClotEntry (2,048 nodes), small MeshGraphNet, GPU",
              test_sims=["clotentry_008", "clotentry_009"], nodes=2048, env=env)
