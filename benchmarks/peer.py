"""thrombojax against its PyTorch peers, side by side on the same graphs (issue 17).

Peers: NVIDIA PhysicsNeMo's MeshGraphNet and Transolver (the latter fed Erwin's MPNN embedding,
as in the study) and the official Erwin (``ErwinTransformer`` from a checkout of the authors'
repository, github.com/maxxxzdn/erwin), each built with thrombojax's study config and the same
parameter count (both counts are printed; a mismatch is flagged in every table). Cases, batch 1:

* rollout step (``step``): graph from the positions + forward + integration, one step;
* N-step rollout (``rollout``, ``--rollout-steps``, default 40): thrombojax's compiled
  ``lax.scan`` rollout against the peer's Python loop of steps;
* forward (``forward``, ``--forward-nodes``, default 27,000 = ClotEntry at full resolution):
  graph + forward; thrombojax builds the graph on its cell grid there (MeshGraphNet and
  Transolver; the issue's table has no Erwin forward);
* train step (``train``): graph, forward, backward, AdamW on one sample.

How (details: ``benchmarks/peer_jax.py``, ``benchmarks/peer_torch.py``,
``benchmarks/peer_common.py``): the inputs of every node count are generated once with numpy
and written to a file both sides read. For every model and node count three long-lived worker
processes prepare the cases (compile or warm up): thrombojax as users get it (tcmalloc
preloaded, as the ``thrombojax`` command does), the peer in its default environment (glibc
malloc) and the peer with tcmalloc preloaded. The parent then runs ``--rounds`` rounds; in a
round every worker in turn (the first one rotating) times each of its cases (``--steps`` calls
of the step and train cases, one call of a rollout or forward), so a change of machine load
hits all sides alike. Printed: median and range per case and side, minor page faults per
learned step, a contention probe per side (the median time of a small two-thread op after
every round: it grows when a worker's threads wait for a core busy with other work), mean
graph edges per node of both sides, the ratios thrombojax / peer ("vs peer default" and "vs
peer same allocator") beside the issue's targets, and the load, device, versions, date and
command. Torch runs with ``torch.set_num_threads(--threads)``.

A missing peer package skips only the models that need it, with how to install it; without
torch nothing runs and the script exits 0.

Usage::

    PYTHONPATH=. python benchmarks/peer.py [--models mgn transolver erwin]
        [--cases step rollout forward train] [--sizes 977 2048] [--rounds 5] [--steps 2]
        [--erwin-src /work/erwin_src] [--out benchmarks/results/peer_cpu.md] [--quick]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import peer_report  # noqa: E402  (benchmarks/ is not a package)

MODELS = ("mgn", "transolver", "erwin")
CASES = ("step", "rollout", "forward", "train")
SIDES = ("thrombojax", "peer default", "peer tcmalloc")

INSTALL = """\
How to install the peer stack (CPU; docs/performance.md):
  pip install torch==2.13.0          # a CPU-only wheel first (PyTorch's CPU wheel index);
                                     # a plain `pip install torch` pulls the CUDA build
  MAX_JOBS=1 pip wheel --no-build-isolation --no-deps torch_scatter torch_cluster -w wheels/
  pip install wheels/*.whl           # (no CPU wheels of these exist on the package index)
  printf 'torch==2.13.0\\ntorchvision==0.28.0\\n' > constraints.txt   # keep the CPU torch
  pip install -c constraints.txt -e '.[peer]'   # physicsnemo, torch_geometric, balltree-erwin
  git clone the official Erwin (github.com/maxxxzdn/erwin) and pass --erwin-src DIR"""


def missing_packages(models: list[str], erwin_src: str) -> dict[str, list[str]]:
    """What each model's peer lacks (module names; an empty list: runnable). No torch import."""
    def absent(*mods):
        return [m for m in mods if importlib.util.find_spec(m) is None]

    need = {"mgn": absent("torch", "physicsnemo", "torch_geometric", "torch_scatter",
                          "torch_cluster"),
            "transolver": absent("torch", "physicsnemo", "torch_cluster"),
            "erwin": absent("torch", "torch_cluster", "balltree", "einops")}
    if not os.path.isfile(os.path.join(erwin_src, "models", "erwin.py")):
        need["erwin"].append(f"the official Erwin source ({erwin_src}/models/erwin.py)")
    return {m: need[m] for m in models}


def _worker(side: str, spec: dict, tcmalloc: str | None) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if k != "LD_PRELOAD"}
    if side != "peer default" and tcmalloc:
        env["LD_PRELOAD"] = tcmalloc
    script = "peer_jax.py" if side == "thrombojax" else "peer_torch.py"
    return subprocess.Popen([sys.executable, os.path.join(HERE, script), json.dumps(spec)],
                            env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)


def _read(proc: subprocess.Popen, until: str, side: str) -> dict:
    while line := proc.stdout.readline():
        try:
            msg = json.loads(line)
        except json.JSONDecodeError:
            print(f"#   [{side}] {line.rstrip()}", flush=True)
            continue
        if until in msg:
            return msg
    raise RuntimeError(f"the {side} worker exited with {proc.wait()} (see its stderr above)")


def run_group(cases: list, sides: list[str], spec: dict, rounds: int, tcmalloc, log) -> dict:
    """Prepare ``cases`` in one worker per side, then alternate the sides for ``rounds`` rounds.

    Returns:
        ``{"ready": {side: msg}, "rounds": {side: [timing, ...]}, "load": [...]}``.
    """
    spec = dict(spec, cases=cases)
    procs, ready = {}, {}
    try:
        for side in sides:  # one prepares (compiles) at a time
            procs[side] = _worker(side, spec, tcmalloc)
            ready[side] = _read(procs[side], "ready", side)
            log(f"#   {side}: ready in {ready[side]['prepare_s']} s "
                f"({ready[side]['allocator']})")
        timings, probes = {side: [] for side in sides}, {side: [] for side in sides}
        for r in range(rounds):
            order = sides[r % len(sides):] + sides[:r % len(sides)]
            for side in order:
                procs[side].stdin.write("go\n")
                procs[side].stdin.flush()
                msg = _read(procs[side], "round", side)
                timings[side] += msg["round"]
                probes[side].append(msg["probe_us"])
            log(f"#   round {r + 1}/{rounds} done, load {peer_report.load()}, probe us "
                + " / ".join(str(probes[s][-1]) for s in sides))
    finally:
        for proc in procs.values():
            proc.stdin.close()
            proc.wait()
    return {"ready": ready, "rounds": timings, "probe_us": probes, "load": peer_report.load()}


def plan(args) -> list[list]:
    """Groups of ``[model, kind, nodes]`` cases; each group gets its own workers."""
    groups = []
    for name in args.models:
        for n in args.sizes:
            kinds = [k for k in args.cases if k != "forward"]
            if kinds:
                groups.append([[name, k, n] for k in kinds])
        if "forward" in args.cases and name != "erwin":
            groups.append([[name, "forward", args.forward_nodes]])
    return groups


def parse(argv: list[str] | None):
    """The command line (see the module docstring; ``--help``)."""
    p = argparse.ArgumentParser(description=__doc__.split("Usage::")[0],
                                epilog=INSTALL, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--models", nargs="+", default=list(MODELS), choices=MODELS)
    p.add_argument("--cases", nargs="+", default=list(CASES), choices=CASES,
                   help="step: rollout step; rollout: N-step rollout; forward: graph + forward "
                        "at --forward-nodes; train: train step")
    p.add_argument("--sizes", nargs="+", type=int, default=[977, 2048],
                   help="node counts of the step, rollout and train cases")
    p.add_argument("--rounds", type=int, default=5, help="rounds alternating the sides")
    p.add_argument("--steps", type=int, default=2,
                   help="timed calls per round of the step and train cases (rollout and "
                        "forward: one)")
    p.add_argument("--rollout-steps", type=int, default=40, help="steps of the rollout case")
    p.add_argument("--forward-nodes", type=int, default=27000,
                   help="node count of the forward case (ClotEntry at full resolution)")
    p.add_argument("--threads", type=int, default=2, help="torch.set_num_threads")
    p.add_argument("--erwin-src", default="/work/erwin_src",
                   help="checkout of the official Erwin (its models/erwin.py)")
    p.add_argument("--out", help="write the report here (markdown) and the raw timings beside "
                                 "it (.json)")
    p.add_argument("--quick", action="store_true",
                   help="smoke run: tiny configs, 256 nodes, 2 rounds, 1 call, 3-step rollouts, "
                        "1,000-node forward")
    args = p.parse_args(argv)
    if args.quick:
        args.sizes, args.rounds, args.steps = [256], 2, 1
        args.rollout_steps, args.forward_nodes = 3, 1000
    return args


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; returns the exit status (0 also when peers are missing)."""
    args = parse(argv)
    lacking = missing_packages(args.models, args.erwin_src)
    if all("torch" in what for what in lacking.values()):
        print(f"skipped: torch not installed (no peer can run: {', '.join(args.models)})")
    else:
        for name, what in lacking.items():
            if what:
                print(f"skipped: {name}: {', '.join(what)} not installed", flush=True)
    models = [m for m in args.models if not lacking[m]]
    if not models:
        print(INSTALL)
        return 0
    if any(lacking.values()):
        print(INSTALL, flush=True)
    args.models = models

    from thrombojax.cli.allocator import find_tcmalloc
    from thrombojax.models.registry import config_to_dict, get_config
    from thrombojax.study import training_defaults

    tcmalloc = find_tcmalloc()
    sides = list(SIDES) if tcmalloc else ["thrombojax", "peer default"]
    env = peer_report.environment(args, tcmalloc)
    lines = peer_report.header(env)
    print("\n".join(lines), flush=True)
    groups = plan(args)
    with tempfile.TemporaryDirectory(prefix="peer_bench_") as tmp:
        from peer_common import write_inputs
        inputs = {}
        for n in sorted({c[2] for g in groups for c in g}):
            inputs[str(n)] = os.path.join(tmp, f"inputs_{n}.npz")
            write_inputs(inputs[str(n)], n)
        spec = {"tiny": args.quick, "inputs": inputs, "repeats": args.steps,
                "rollout_steps": args.rollout_steps, "threads": args.threads,
                "erwin_src": args.erwin_src,
                "configs": {m: config_to_dict(get_config(m, tiny=args.quick)) for m in models},
                "lr": {m: float(training_defaults(m)["lr"]) for m in models}}
        results, progress = [], ["", "Progress (as printed):", "", "```"]

        def log(line: str) -> None:
            print(line, flush=True)
            progress.append(line)

        for i, group in enumerate(groups):
            log(f"# {group[0][0]}: {', '.join(f'{k} {n}' for _, k, n in group)}")
            results.append(run_group(group, sides, spec, args.rounds, tcmalloc, log))
            env["load_avg_end"] = peer_report.load()
            report = peer_report.tables(results, sides, args, env)
            if args.out:  # after every group, so an interrupted run leaves what it measured
                done = [] if i + 1 == len(groups) else [
                    "", f"(partial: {i + 1} of {len(groups)} worker groups measured)"]
                peer_report.write(args.out, lines + report + done + progress + ["```"],
                                  results, env)
    print("\n".join(report), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
