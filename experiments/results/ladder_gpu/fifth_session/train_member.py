"""Train member SEED of a ladder ensemble rung on its own, so that the members of one rung can
train at the same time (one process each) before ``experiments/ladder.py`` evaluates the rung
and finds them trained. The same call the ladder makes (``ladder._train_rung``), with the
ladder's recipe, folder and a fixed epoch count.

    python train_member.py OUT RUNG SEED DATA NODES TEST VAL EPOCHS
"""
import dataclasses
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[3]))
import ladder  # noqa: E402
from ladder_rungs import COMMON, RUNGS  # noqa: E402

out, rung_name, seed = pathlib.Path(sys.argv[1]), sys.argv[2], int(sys.argv[3])
data, nodes, epochs = sys.argv[4], int(sys.argv[5]), int(sys.argv[8])
split = {"test_sims": sys.argv[6].split(","), "val_sims": sys.argv[7].split(",")}
rung = next(r for r in RUNGS if r.name == rung_name)
if seed == 0:  # member 0 is the reused rung's own training (the ladder's folder for it)
    folder = out / (rung.reuse or rung.name)
    member = dataclasses.replace(rung, name=rung.reuse or rung.name)
else:
    folder = ladder._member_folder(rung, out, seed)
    member = ladder.member_rung(rung, seed)
folder.mkdir(parents=True, exist_ok=True)
print(ladder._train_rung(member, data, folder, split, 0.0, epochs, epochs, nodes, COMMON))
