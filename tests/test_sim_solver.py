"""Physics acceptance of the solver on the tiny presets, and float32 vs float64."""

import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from thrombojax.sim import generate, geometry, presets
from thrombojax.sim.cases import build_case, build_vessel
from thrombojax.sim.clot import tet_volumes
from thrombojax.sim.solver import run
from thrombojax.types import NodeType

TINY = ("bendvessel-tiny", "clotentry-tiny")


@pytest.fixture(scope="module", params=TINY)
def result(request):
    preset = presets.get_preset(request.param)
    sim = generate.simulate(preset, 1, seed=0)
    cl, _ = build_vessel(preset, 1, 0)
    rot = geometry.rotation_matrix(preset.rotation_axis, sim.attrs["rotation_deg"])
    return preset, sim, cl, rot


def _clot_frames(sim, rot):
    pos = np.asarray(sim.positions, np.float64) @ rot  # undo the output rotation
    return pos[:, sim.node_type == NodeType.CLOT]


def test_shapes_and_attributes(result):
    preset, sim, _, _ = result
    assert sim.positions.shape[0] == preset.n_frames + 1
    assert np.all(np.isfinite(sim.positions))
    for key in ("dt", "solver_wall_time_s", "reference_wall_time_s", "rotation_deg", "seed"):
        assert key in sim.attrs
    assert sim.attrs["reference_wall_time_s"] == preset.reference_wall_time_s
    for key in ("oversize", "friction", "young", "poisson", "roll_deg", "drive_ratio"):
        lo, hi = getattr(
            preset,
            {"young": "young_range", "poisson": "poisson_range", "roll_deg": "roll_range"}.get(
                key, f"{key}_range"
            ),
        )
        assert lo <= sim.attrs[key] <= hi


def test_no_inverted_tets(result):
    _, sim, _, rot = result
    clot = _clot_frames(sim, rot)
    vol = np.stack([tet_volumes(x, sim.clot_cells) for x in clot])
    assert vol.min() > 0.0
    assert sim.attrs["min_J"] > 0.3


def test_wall_penetration_below_two_percent(result):
    _, sim, cl, rot = result
    worst = 0.0
    for x in _clot_frames(sim, rot):
        d = geometry.signed_distance_np(cl, x)
        pen = np.where(d["outside"], 0.0, np.maximum(-d["phi"], 0.0)) / d["radius"]
        worst = max(worst, pen.max())
    assert worst < 0.02
    assert sim.attrs["max_penetration_rel"] < 0.02  # over every substep, not only frames


def test_clot_starts_inside_and_leaves(result):
    _, sim, cl, rot = result
    clot = _clot_frames(sim, rot)
    first = geometry.signed_distance_np(cl, clot[0])
    assert not first["outside"].any() and first["phi"].min() > 0
    last = geometry.signed_distance_np(cl, clot[-1])
    assert last["outside"].all() and np.all(last["beyond"] > 0)


def test_quasi_static_before_exit(result):
    _, sim, _, _ = result
    # time average over the frames after the drive ramp and before any node leaves
    assert 0.0 < sim.attrs["kinetic_to_elastic"] < 0.3


def test_vessel_nodes_never_move(result):
    _, sim, _, _ = result
    wall = sim.positions[:, sim.node_type == NodeType.VESSEL]
    assert np.array_equal(wall, np.broadcast_to(wall[0], wall.shape))
    assert sim.wall_cells.min() >= np.sum(sim.node_type == NodeType.CLOT)


_X64_SCRIPT = """
import jax, sys
jax.config.update("jax_enable_x64", True)
import numpy as np
sys.path.insert(0, {root!r})
from tests.test_sim_solver import short_run
np.save({out!r}, short_run())
"""


def short_run(n_steps=600):
    """Final clot positions after ``n_steps`` substeps of bendvessel-tiny case 0 (any dtype)."""
    preset = presets.get_preset("bendvessel-tiny")
    case = build_case(preset, 0, 0)
    cl = jax.tree.map(jnp.asarray, case.centreline)
    res = run(
        case.params,
        cl,
        jnp.asarray(case.tets),
        n_buffer=preset.n_buffer,
        max_substeps=n_steps,
        elem_bulk=preset.elem_bulk,
    )
    assert int(res.steps) >= n_steps
    return np.asarray(res.frames[int(res.count) - 1])


def test_float32_matches_float64(tmp_path):
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    out = str(tmp_path / "x64.npy")
    env = dict(os.environ, JAX_PLATFORMS="cpu")
    subprocess.run(
        [sys.executable, "-c", _X64_SCRIPT.format(root=root, out=out)],
        check=True,
        env=env,
        cwd=root,
    )
    x64 = np.load(out)
    x32 = short_run()
    assert x64.dtype == np.float64 and x32.dtype == np.float32
    assert np.abs(x64 - x32).max() < 2e-3  # in vessel radii
