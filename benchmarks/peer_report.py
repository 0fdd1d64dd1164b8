"""The report of ``benchmarks/peer.py``: environment header, per-case table, summary, targets.

Ratios are thrombojax's median time / the peer's median time over all timed calls of all
rounds (below 1: thrombojax is faster). "vs peer same allocator" compares with the peer under
tcmalloc, the allocator thrombojax runs with (without tcmalloc on the machine both sides run
glibc and the two ratios are the same). Issue 17's targets are printed beside them.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import statistics
import subprocess
import sys

__all__ = ["TARGETS", "load", "environment", "header", "tables", "write"]

TARGETS: dict[str, dict] = {
    "train": {"sizes": None, "peer default": 0.5, "peer same": 0.6},
    "step": {"sizes": (2048,), "peer default": 0.33, "peer same": 0.33},
}
"""Issue 17: train step <= 0.5x the peer (default) and <= 0.6x (same allocator); rollout step
<= 0.33x at 2,048 nodes. ``sizes``: the node counts a target applies to (None: all)."""

LABELS = {"step": "rollout step", "rollout": "{r}-step rollout", "forward": "forward",
          "train": "train step"}


def load() -> list[float]:
    """1, 5 and 15-minute load averages."""
    return [round(x, 2) for x in os.getloadavg()]


def _version(dist: str) -> str | None:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


def environment(args, tcmalloc: str | None) -> dict:
    """Where and how it ran: thrombojax's record (the processor included) plus the PyTorch stack
    and the settings."""
    from thrombojax.eval.tables import environment as base
    env = base()
    env["command"] = " ".join(["python", "benchmarks/peer.py", *sys.argv[1:]])
    env["nice"] = os.nice(0)
    env["load_avg_start"] = env.pop("load_avg_1_5_15")
    for dist in ("torch", "nvidia-physicsnemo", "torch_cluster", "torch_scatter",
                 "torch_geometric", "balltree-erwin", "einops"):
        env[dist] = _version(dist)
    git = subprocess.run(["git", "-C", args.erwin_src, "rev-parse", "HEAD"], capture_output=True,
                         text=True)
    env["erwin_src"] = f"{args.erwin_src} @ {git.stdout.strip() or 'unknown commit'}"
    env["tcmalloc"] = tcmalloc or "not installed (every side runs glibc malloc)"
    env["settings"] = (f"rounds {args.rounds}, {args.steps} timed calls per round (step, train), "
                       f"{args.rollout_steps}-step rollouts, forward at {args.forward_nodes} "
                       f"nodes, torch threads {args.threads}, batch 1"
                       + (", TINY configs (--quick)" if args.quick else ""))
    return env


def header(env: dict) -> list[str]:
    """The environment as ``# key: value`` lines in a code block."""
    return ["# benchmarks/peer.py: thrombojax vs PyTorch peers", "", "```",
            *[f"# {k}: {v}" for k, v in env.items()], "```"]


def _stats(rows: list[dict]) -> dict:
    ms = [r["ms"] for r in rows]
    return {"median": statistics.median(ms), "min": min(ms), "max": max(ms),
            "faults": statistics.median(r["faults_per_step"] for r in rows)}


def _collect(results: list[dict], sides: list[str]) -> dict:
    """``{key: {"sides": {side: stats}, "info": {side: info}}}`` over every group."""
    out = {}
    for res in results:
        for side in sides:
            for key, info in res["ready"][side]["info"].items():
                entry = out.setdefault(key, {"sides": {}, "info": {}, "load": res["load"],
                                             "probe": res.get("probe_us", {})})
                entry["info"][side] = info
                entry["sides"][side] = _stats([r for r in res["rounds"][side] if r["key"] == key])
    return out


def _median(values) -> str:
    values = [v for v in values or [] if v is not None]
    return f"{statistics.median(values):.0f}" if values else "-"


def _target(kind: str, n: int, r_default: float, r_same: float) -> str:
    t = TARGETS.get(kind)
    if t is None or (t["sizes"] is not None and n not in t["sizes"]):
        return ""
    ok = r_default <= t["peer default"] and r_same <= t["peer same"]
    return (f"<= {t['peer default']} / <= {t['peer same']}: "
            f"{'met' if ok else 'MISSED'}")


def tables(results: list[dict], sides: list[str], args, env: dict) -> list[str]:
    """The per-case table, the summary in the issue's layout and the parameter check."""
    data = _collect(results, sides)
    same = sides[-1]
    out = ["", "## Per case (ms per call; faults: minor page faults per learned step, median)", "",
           "| model | case | nodes | " + " | ".join(f"{s} median (range)" for s in sides)
           + " | vs peer default | vs peer same allocator | issue target (default / same) | "
           "faults/step " + " / ".join(sides) + " | edges per node thrombojax / peer | params "
           "thrombojax / peer | probe us (median) " + " / ".join(sides) + " | load at end |",
           "|" + "---|" * (len(sides) + 11)]
    ratios, mismatch = {}, []
    for key, e in data.items():
        name, kind, n = key.split("|")
        n = int(n)
        st, info = e["sides"], e["info"]
        r_def = st["thrombojax"]["median"] / st["peer default"]["median"]
        r_same = st["thrombojax"]["median"] / st[same]["median"]
        ratios[(name, kind, n)] = (r_def, r_same)
        p_tj, p_peer = info["thrombojax"]["params"], info["peer default"]["params"]
        flag = "" if p_tj == p_peer else " **MISMATCH**"
        if flag:
            mismatch.append(f"{name}: thrombojax {p_tj:,} vs peer {p_peer:,}")
        edges = (f"{info['thrombojax'].get('edges_per_node', '-')} / "
                 f"{info['peer default'].get('edges_per_node', '-')}")
        cells = [f"{st[s]['median']:.1f} ({st[s]['min']:.1f}-{st[s]['max']:.1f})" for s in sides]
        faults = " / ".join(f"{st[s]['faults']:.0f}" for s in sides)
        probe = " / ".join(_median(e["probe"].get(s)) for s in sides)
        label = LABELS[kind].format(r=args.rollout_steps)
        out.append(f"| {name} | {label} | {n:,} | " + " | ".join(cells)
                   + f" | {r_def:.2f} | {r_same:.2f} | {_target(kind, n, r_def, r_same)} | "
                   f"{faults} | {edges} | {p_tj:,} / {p_peer:,}{flag} | {probe} | {e['load']} |")
    out += _summary(ratios, args)
    out += ["", "Parameter counts: " + ("equal on both sides for every model."
                                        if not mismatch else
                                        "!!! MISMATCH: " + "; ".join(mismatch))]
    out += ["", f"Load (1, 5, 15 min): start {env['load_avg_start']}, "
            f"end {env['load_avg_end']}."]
    return out


def _summary(ratios: dict, args) -> list[str]:
    """Rows: models; columns: the cases, each "977 / 2,048" ratios vs default and vs same."""
    sizes = " / ".join(f"{n:,}" for n in args.sizes)
    cols = [("step", f"rollout step {sizes}"),
            ("rollout", f"{args.rollout_steps}-step rollout {sizes}"),
            ("forward", f"forward {args.forward_nodes:,}"), ("train", f"train step {sizes}")]
    cols = [c for c in cols if c[0] in args.cases]
    head = []
    for _, title in cols:
        head += [f"{title} vs peer default", f"{title} vs peer same allocator"]
    out = ["", "## Summary: thrombojax / peer (median time ratio; below 1: thrombojax faster)", "",
           "| model | " + " | ".join(head) + " |", "|" + "---|" * (len(head) + 1)]
    for name in args.models:
        row = []
        for kind, _ in cols:
            ns = [args.forward_nodes] if kind == "forward" else args.sizes
            for i in (0, 1):
                vals = [ratios.get((name, kind, n)) for n in ns]
                row.append(" / ".join("-" if v is None else f"{v[i]:.2f}" for v in vals))
        out.append(f"| {name} | " + " | ".join(row) + " |")
    out += ["", "Issue 17's targets: train step <= 0.5x peer default and <= 0.6x peer same "
            "allocator; rollout step <= 0.33x at 2,048 nodes (met / MISSED per row above)."]
    return out


def write(path: str, lines: list[str], results: list[dict], env: dict) -> None:
    """Write the markdown report to ``path`` and the raw timings to ``path`` with ``.json``."""
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")
    with open(os.path.splitext(path)[0] + ".json", "w") as f:
        json.dump({"environment": env, "groups": results}, f, indent=1)
