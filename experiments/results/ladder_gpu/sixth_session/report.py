"""Write ``ce/table.md``, ``ladder.json`` and ``error_per_step.png`` from the device's two
``result.json`` files. The device's third call ran ``experiments/ladder.py`` once per recipe,
side by side (the command below), and each invocation wrote the folder's report with its own
rung only; this joins them. The environment is the device's, as that call's ladder recorded it
(``ce/device_environment.json``), with the command of both invocations.

    python experiments/results/ladder_gpu/sixth_session/report.py
"""
import json
import pathlib
import sys

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[2]))  # experiments/
from ladder_report import write_reports  # noqa: E402

out = HERE / "ce"
names = ("follow_kstep_last_ens3_guards", "follow_kstep6_last_ens3_guards")
results = {n: json.loads((out / n / "result.json").read_text()) for n in names}
env = {**json.loads((out / "device_environment.json").read_text())["environment"],
       "command": "for R in follow_kstep_last follow_kstep6_last: ladder.py --dataset "
                  "/root/d/clotentry.h5 --nodes 2048 --test clotentry_008,clotentry_009 --val "
                  "clotentry_007 --epochs E --out /root/d/ce --rungs ${R}_ens3_guards (E = 8 "
                  "and 6; the two side by side; the joint report written afterwards by "
                  "report.py on a CPU machine)"}
print(write_reports(out, results, title="ClotEntry (2,048 nodes), small MeshGraphNet, GPU",
                    test_sims=["clotentry_008", "clotentry_009"], nodes=2048, env=env))
