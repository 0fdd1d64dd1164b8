"""Score the sixth device session's k-step models without the guards, on a CPU machine: each
recipe's ensemble of three rolled out alone, and each member alone (the device scored them
guarded; its time ran out before this). Reads the checkpoints brought back from the device
(``checkpoints/last`` of every run; not committed) and writes ``<OUT>/<rung>/result.json`` and
``<OUT>/table.md`` with this machine's environment.

    python experiments/results/ladder_gpu/sixth_session/score_cpu.py CE DATA OUT

CE: the folder holding ``follow_kstep_last/`` and ``follow_kstep6_last/`` (each ``run/``,
``member_1/run/``, ``member_2/run/``); DATA: ClotEntry (``thrombojax generate clotentry``).
Resumable: a rung whose ``result.json`` exists is kept.
"""
import dataclasses
import json
import pathlib
import sys
import time

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[2]))  # experiments/
from ladder_eval import evaluate_runs, members_alone  # noqa: E402
from ladder_report import write_reports  # noqa: E402
from ladder_rungs import RUNGS  # noqa: E402

from thrombojax.io.outputs import atomic_write_text  # noqa: E402

ce, data, out = pathlib.Path(sys.argv[1]), sys.argv[2], pathlib.Path(sys.argv[3])
rungs = {r.name: r for r in RUNGS}
results = {}
for recipe in ("follow_kstep_last", "follow_kstep6_last"):
    rung = rungs[f"{recipe}_seeds3"]
    done = out / rung.name / "result.json"
    if not done.is_file():
        runs = [ce / recipe / "run"] + [ce / recipe / f"member_{s}" / "run" for s in (1, 2)]
        t = time.perf_counter()
        res = evaluate_runs(runs, data, False, 2048, which="last")
        res["members_alone"] = members_alone(runs, data, False, 2048, "last")
        res.update(rung=dataclasses.asdict(rung) | {"train": {k: str(v) for k, v in
                                                              rung.train.items()}},
                   seconds=time.perf_counter() - t)
        done.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(done, json.dumps(res, indent=1))
        print(f"{rung.name}: {res['mean']['final_centroid_r']:.2f} r", flush=True)
    results[rung.name] = json.loads(done.read_text())
print(write_reports(out, results, title="ClotEntry (2,048 nodes), small MeshGraphNet trained on "
                    "an H200, scored on this CPU", test_sims=["clotentry_008", "clotentry_009"],
                    nodes=2048))
