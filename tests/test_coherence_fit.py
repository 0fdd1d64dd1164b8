"""The coherence guard's tolerance fitted on true clots (``--coherence-tolerance auto``)."""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from thrombojax.errors import DatasetError
from thrombojax.eval.coherence_fit import clot_deviations, fit_coherence
from thrombojax.types import NodeType


def _sim(growth: np.ndarray, seed: int = 0) -> SimpleNamespace:
    """A clot of 40 nodes beside 10 vessel nodes, moved and turned rigidly at every frame and
    grown about its centroid by ``1 + growth[t]``: its deviation from the best rigid copy of
    frame 0 is exactly ``growth[t] * |x_i - c|``."""
    rng = np.random.default_rng(seed)
    clot = rng.normal(size=(40, 3))
    clot -= clot.mean(0)
    vessel = rng.normal(size=(10, 3)) * 5
    frames = []
    for t, g in enumerate(growth):
        turn = Rotation.from_rotvec([0.0, 0.1 * t, 0.05 * t]).as_matrix()
        frames.append(np.concatenate([(1 + g) * clot @ turn.T + [0.3 * t, 0.0, 0.0], vessel]))
    node_type = np.r_[np.full(40, NodeType.CLOT), np.full(10, NodeType.VESSEL)]
    truth = np.asarray(growth)[:, None] * np.linalg.norm(clot, axis=1)[None]
    return SimpleNamespace(positions=np.float32(frames), node_type=node_type, truth=truth)


def _dataset(sims: dict, path: str = "fake.h5"):
    return type("DS", (), {"path": path, "__getitem__": lambda self, n: sims[n]})()


def test_a_rigidly_moving_clot_deviates_by_nothing_and_a_growing_one_by_its_growth():
    rigid = _sim(np.zeros(8))
    assert np.abs(clot_deviations(rigid.positions, rigid.node_type, 0, 1.0)).max() < 1e-5
    grows = _sim(np.linspace(0.0, 0.2, 8))
    dev = clot_deviations(grows.positions, grows.node_type, 0, 2.0)  # in radii of 2 units
    assert dev.shape == (7, 40)  # the frames after the start, the clot's nodes
    np.testing.assert_allclose(dev, grows.truth[1:] / 2.0, atol=1e-4)
    # the reference is the start frame: from frame 3 on, the growth is counted from there
    from_3 = clot_deviations(grows.positions, grows.node_type, 3, 1.0)
    growth = np.linspace(0.0, 0.2, 8)
    np.testing.assert_allclose(from_3, (grows.truth[4:] / growth[4:, None])
                               * (growth[4:, None] - growth[3]), atol=1e-4)


def test_fit_coherence_is_the_quantile_of_the_true_deviations():
    """Pooled over the chosen simulations; a clot that deforms more gets a wider tolerance;
    no simulations, a bad quantile or a start past the frames are errors naming the file."""
    still, grows = _sim(np.linspace(0.0, 0.05, 6)), _sim(np.linspace(0.0, 0.4, 6), seed=1)
    ds = _dataset({"a": still, "b": grows})
    fit = fit_coherence(ds, ["a"], 1.0, 0)
    assert fit["quantile"] == 0.95 and fit["start"] == 0 and fit["simulations"] == ["a"]
    assert fit["pairs"] == 5 * 40
    assert abs(fit["coherence_r"] - np.quantile(still.truth[1:], 0.95)) < 1e-4
    assert abs(fit["largest_r"] - still.truth.max()) < 1e-4
    both = fit_coherence(ds, ["a", "b"], 1.0, 0, quantile=0.5)
    want = np.quantile(np.r_[still.truth[1:].ravel(), grows.truth[1:].ravel()], 0.5)
    assert abs(both["coherence_r"] - want) < 1e-4
    assert fit_coherence(ds, ["b"], 1.0, 0)["coherence_r"] > 4 * fit["coherence_r"]
    with pytest.raises(DatasetError, match="fake.h5: no simulations"):
        fit_coherence(ds, [], 1.0, 0)
    with pytest.raises(DatasetError, match="quantile"):
        fit_coherence(ds, ["a"], 1.0, 0, quantile=1.5)
    with pytest.raises(DatasetError, match="fake.h5: simulation 'a': .*start frame 6"):
        fit_coherence(ds, ["a"], 1.0, 6)
    with pytest.raises(DatasetError, match="no frame after"):
        fit_coherence(ds, ["a"], 1.0, 5)
