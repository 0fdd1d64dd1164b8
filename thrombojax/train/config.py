"""The training configuration: the study's knobs, with its values as defaults.

Defaults follow the study: 300 epochs, 10 warm-up epochs then cosine decay, AdamW, random
rotations up to pi radians, and each model's batch size and learning rate
(:data:`thrombojax.study.TRAINING`; the model config holds architecture only, e.g. the graph
``radius``, set through ``model_config``). Choices where the study is silent:

* ``max_rotation`` is in **radians** (the thesis quotes pi and 1.5 radians); the CLI also accepts
  ``pi``, ``pi/2``, ``0.5pi``, ``2*pi`` and degrees with a ``deg`` suffix (``90deg``).
* ``bary_ratio`` is generated samples per real sample (the study's best on BendVessel, 1:2, is
  ``2.0``); default 0 (off) since the study used it on BendVessel only.
* ``nodes_per_sample`` ``None`` uses all nodes (BendVessel); the study used 2048 on ClotEntry.
* ``weight_decay`` 0.01 (PyTorch's AdamW default), no gradient clipping, no training noise.
* ``n_val = 2``, ``n_test = 1`` simulations, split with ``split_seed`` (independent of ``seed``
  so seeds vary the training only, as in the study's 5-seed table).
"""

from __future__ import annotations

import dataclasses
import json
import math
import pathlib
from typing import Any

from thrombojax.errors import ConfigError
from thrombojax.graph.frame import FRAMES
from thrombojax.train.angles import parse_angle
from thrombojax.train.checks import check_train_values

__all__ = ["TrainConfig", "RunConfig", "SELECT_BY", "CHECKPOINTS", "parse_angle",
           "load_config_file"]

SELECT_BY = ("mse", "rollout", "last")
"""What picks the ``best`` checkpoint: the one-step validation MSE, the validation rollout
(:mod:`thrombojax.train.validation`), or the last epoch."""

CHECKPOINTS = ("best", "last")
"""The checkpoints a run keeps (``run_dir/checkpoints/<name>``)."""


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """Everything a training run needs besides the dataset, the model name and the output.

    Attributes:
        epochs: passes over the (real + generated) training samples.
        batch_size: samples per step (``None``: the study's value for the model).
        lr: peak learning rate (``None``: the study's value for the model).
        warmup_epochs: linear warm-up length in epochs (then cosine decay to 0).
        weight_decay: AdamW decoupled weight decay.
        grad_clip: global-norm gradient clip (``None``: off).
        max_rotation: random rotation up to this angle in radians (0: off).
        uniform_rotation: the rotation's angle is drawn from the uniform measure on the
            rotations (:func:`thrombojax.data.augment.random_rotation`: with ``max_rotation =
            pi`` every orientation equally likely), not uniform in ``[0, max_rotation]``.
        nodes_per_sample: subsample this many nodes per sample (``None``: all).
        bary_ratio: generated (BaryCentricSampling) samples per real sample.
        bary_radius: radius of the graph whose triangles are sampled (``None``: model radius).
        bary_max_neighbors: neighbour cap of that graph (``K``; ``K (K - 1) / 2`` triangle
            candidates per node).
        noise_std: training noise on s_t, in vessel radii (the dataset's radius,
            :func:`thrombojax.data.radius.vessel_radius`, converted to scaled coordinates);
            MeshGraphNets' recipe, learning-to-simulate's random walk with one velocity.
        noise_gamma: fraction of the noise the model learns to remove from the next position.
        noise_walk: with ``history > 1``, the noise is a random walk over every input frame
            (learning-to-simulate's), not on s_t alone (:mod:`thrombojax.train.noise`).
        noise_shared: share of the noise variance common to every clot node of a window, in
            [0, 1] (0: independent per node; :mod:`thrombojax.train.noise`).
        wall_noise: wall noise, in vessel radii: clot nodes within this distance of the wall
            are moved through it (half of them, to a depth of this times ``|N(0, 1)|``) in every
            input frame and by half as much in the targets, so the model learns to bring a node
            that crossed the wall back (0: off; :func:`thrombojax.train.noise.add_wall_noise`).
        history_noise: history noise, in vessel radii: the whole clot shifted by one
            ``N(0, history_noise^2)`` vector in the frames before s_{t-1} (needs ``history``
            >= 2), the target unchanged, so the model does not carry a clot-wide acceleration
            over from its history (0: off; :func:`thrombojax.train.noise.add_history_noise`).
        speed_noise: speed noise, a fraction (dimensionless): the clot's input motion scaled
            by ``1 + e``, ``e ~ N(0, speed_noise^2)`` per window, s_t and the target unchanged,
            so the model is shown a clot off its speed and the true next frame (0: off;
            :func:`thrombojax.train.noise.add_speed_noise`). ``speed_noise_steady``: noise only
            the windows whose true clot keeps its speed to s_{t+1} within this fraction (0: all).
        direction_noise: direction noise, radians: the clot's input motion turned by one
            rotation per window, angle vector ``N(0, direction_noise^2 I)``, s_t and the target
            unchanged, so the model is shown a clot coming in from off its path and the true
            next frame (0: off; :func:`thrombojax.train.noise.add_direction_noise`).
        swell_noise: swell noise, a fraction (dimensionless): the clot of the input frames
            scaled about its centroid by ``1 + e``, ``e ~ N(0, swell_noise^2)`` per window
            (with a random rate over the input frames), the targets by ``1 + e / 2``, so the
            model learns to take back a swelling of the clot, which a rollout's clot otherwise
            keeps and grows (0: off; :func:`thrombojax.train.shape_noise.add_swell_noise`).
        stretch_noise: stretch noise, a fraction: the same draw applied along the clot's
            motion only (the front moved ahead of the rear), which rollouts' clots otherwise
            keep and grow (0: off; :func:`thrombojax.train.shape_noise.add_stretch_noise`).
        time_scale: time-scaling augmentation, the largest factor ``F`` (>= 1): each
            window's clot motion played ``k = F^u`` times as fast, ``u ~ U(-1, 1)`` (velocities
            ``k``, accelerations ``k^2`` times), so a dataset at another frame rate or a clot
            driven faster is not outside the training speeds (1: off;
            :func:`thrombojax.train.noise.time_scale_window`).
        clot_mean_weight: extra weight (>= 0) of the clot-wide error in the training loss:
            the squared error of the clot's mean normalised acceleration is added this many
            times more (:mod:`thrombojax.train.loss`). A rollout integrates a clot-wide error
            step after step, so this is the part of the one step a rollout's end position
            depends on; ``train_loss`` includes the weighted term, validation's ``val_loss``
            stays the plain per-node MSE (0: off).
        wall_loss_weight: weight (>= 0) of the wall term in the training loss: the squared
            distance by which a predicted clot node lies further through the vessel wall than
            the true one, in units of the normalised error, averaged over the clot nodes
            (:mod:`thrombojax.train.wall_loss`): the model pays more for an outward error than
            for an inward one (what it did to rollouts: ``docs/rollouts.md``). ``train_loss``
            includes it, ``val_loss`` does not (0: off).
        speedup_weight: extra weight (>= 0) in the training loss of the windows whose true
            clot speeds up: faster from s_t to s_{t+1} than ``1 + speedup_fraction`` (>= 0,
            default 0.1) times its speed from s_{t-1} to s_t, as where it leaves the vessel
            (:mod:`thrombojax.train.speedup`; 0: off). ``val_loss`` stays unweighted.
        average_weights: weight averaging, a share in [0, 1] of the training's optimiser
            steps: the model is the plain mean of the weights after each of the last
            ``round(share x steps)`` steps (stochastic weight averaging, Izmailov et al. 2018,
            over the tail of the cosine decay); it is what validation measures and checkpoints
            hold, the optimiser's own weights travel in the checkpoint for ``--resume``
            (:func:`thrombojax.train.averaging.average_weights`; 0: off).
        seed: initialisation, data order, augmentations.
        split_seed: which simulations are validation / test.
        n_val, n_test: simulations held out for validation / test.
        train_sims, val_sims, test_sims: a split by name instead (any of them given: the
            named simulations; training defaults to every simulation not named elsewhere).
        skip_frames: first frames never used as the frame t of a window (default 0: every
            window, the study's single-step setting).
        rollout_steps: k of the k-step unrolled loss (1: the single-step loss; windows of
            ``pushforward_steps + k + history + 1`` frames, :attr:`window_length`).
        pushforward_steps: steps applied without gradients before the loss steps
            (push-forward training; 0: off).
        pushforward_guards: pass every push-forward step's prediction through the rollout's
            coherence and containment guards before the next step reads it, so the loss starts
            from the state a guarded rollout is in (:mod:`thrombojax.train.push_guards`; needs
            ``pushforward_steps >= 1``; the windows are led by their simulation's first frame).
        input_guards: pass the input frames of every training window (after the training
            noise) through the rollout's coherence and containment guards, the target still the
            true next frame, so the model learns what to do from the guarded states of a
            guarded rollout without a push-forward pass (:mod:`thrombojax.train.push_guards`;
            the windows are led by their simulation's first frame).
        guard_coherence: with ``pushforward_guards`` or ``input_guards``, coherence's
            tolerance in vessel radii (>= 0; default 0.2, about what ``thrombojax rollout
            --coherence-tolerance auto`` fits on BendVessel).
        curriculum_epochs: grow k linearly from 1 to ``rollout_steps`` over this many epochs
            (0: k from the start). Validation always uses the final k.
        frame: the frame the learned step works in: ``"global"`` (the dataset's axes) or
            ``"vessel"`` (the rigid vessel's principal axes,
            :func:`thrombojax.graph.frame.vessel_frame`: invariant to the vessel's orientation up
            to rounding).
        wall_features: cutoff, in vessel radii, of the per-node distance and direction to the
            nearest vessel node appended to the clot nodes' inputs (0: off;
            :func:`thrombojax.graph.wall_nodes.wall_node_features`).
        wall_signed: with ``wall_features``, the features are the signed distance to the wall
            (positive outside) and its outward normal instead
            (:func:`thrombojax.graph.wall_nodes.signed_wall_features`).
        wall_clot_mean: with ``wall_features``, every clot node also gets the clot-wide mean
            of the wall distance feature, the room the whole clot has in the vessel
            (:func:`thrombojax.graph.wall_nodes.clot_wall_mean`).
        axis_features: width, in vessel radii, of the local vessel axis's neighbourhood: clot
            nodes' inputs get their velocity split along and across the vessel's axis
            (0: off; :func:`thrombojax.graph.vessel_axis.axis_velocity_features`).
        follow_axis: width, in vessel radii, of the vessel axis of the step's prior: > 0, the
            step moves each clot node along the vessel at its current speed
            (:func:`thrombojax.graph.vessel_axis.follow_axis_offset`) and the model learns the
            rest (the target statistics stay those of the acceleration); 0: constant velocity.
        lateral_hold: width, in vessel radii, of the vessel axis of the step's lateral hold:
            > 0, the clot-wide mean of the model's acceleration across the vessel's axis is
            taken out, so the clot moves sideways only as its prior turns it and as it deforms
            (:func:`thrombojax.graph.vessel_axis.clot_lateral_mean`); 0: off.
        outlet_features: width, in vessel radii, of the vessel neighbourhood whose offset along
            the clot's motion tells clot nodes where the clot is against the vessel's open ends
            (per node and clot-wide; negative nearing an outlet), so that the step can see the
            outlet coming (0: off; :func:`thrombojax.graph.vessel_axis.outlet_features`).
        shape_features: length, in vessel radii, that clot nodes' place along the clot's motion
            and the clot's length and width are given over, so the step sees a stretched clot
            (0: off; :func:`thrombojax.graph.clot_shape.clot_shape_features`).
        clearance_features: length, in vessel radii, that the distance from the clot's
            centroid to the nearest vessel node is divided by and given to every clot node:
            the vessel's width where the clot stands, which sets its speed, read through the
            centroid alone (0: off; :func:`thrombojax.graph.clearance.clot_clearance`).
        section_features: length, in vessel radii, that the width of the vessel's
            cross-section at the clot's centroid is divided by and given to every clot node
            (also the unit of its windows): the width that sets the clot's speed, which does
            not change when the clot drifts across the vessel (0: off;
            :func:`thrombojax.graph.section.clot_section_features`).
        centre_pull: with ``follow_axis``, the share in [0, 1] of the clot centroid's offset
            from the middle of the vessel's cross-section (beyond ``centre_tolerance``) that
            the prior takes back per step, by tilting its velocities toward the middle at
            their speed (0: off; :func:`thrombojax.graph.section.centre_pull`).
        centre_tolerance: the centroid's offset from the middle, in vessel radii, that the
            centring pull leaves alone; ``"auto"``: the median of the true clots' offsets over
            the training simulations' frames
            (:func:`thrombojax.train.centre_fit.fit_pull_tolerance`).
        rest_edges: the step also reads the clot's rest state (the simulation's first frame)
            and MeshGraphNet's clot-clot edges get their rest-state displacement beside the
            current one, so the step sees each edge's strain (DeepMind's deforming plate;
            :mod:`thrombojax.simulator.previous`); every training window carries one more frame.
        start_speed: the step also reads the clot's start speed, its speed in the true frames a
            rollout starts from (:mod:`thrombojax.simulator.start_speed`); two more frames a window.
            ``start_speed_noise`` F: in training that speed times ``1 + e``, ``e ~ N(0, F^2)``;
            ``start_span`` K: its mean over the K frames before the start (from rest at ``T0``).
        history: frames before t the learned step reads (1: the velocity alone; H >= 2: also
            the H - 1 accelerations before t, :mod:`thrombojax.simulator.step`); windows grow
            by H - 1 frames.
        stop_history_gradient: with ``history > 1`` and an unrolled loss, no gradient through
            the history features (:class:`thrombojax.simulator.step.LearnedStep`).
        tiny: start from the model's tiny config (tests, smoke runs).
        model_config: overrides of the model config fields (architecture, graph radius).
        checkpoint_every: also save the last checkpoint every this many steps (0: each epoch).
        select_by: what picks the ``best`` checkpoint: ``"mse"`` (the lowest one-step
            validation MSE, the study's), ``"rollout"`` (each epoch also rolls the model out
            alone on every validation simulation, logged as ``val_rollout_*``; the lowest
            full-length rollout MSE; :mod:`thrombojax.train.validation`) or ``"last"`` (the
            last epoch's: the end of the learning-rate decay).
        init_from: a run directory whose weights start this training instead of random ones
            (fine-tuning, e.g. with an unrolled loss after single-step training; the same
            model and step inputs; the optimiser starts afresh; ``""``: off).
        init_which: which checkpoint of ``init_from``: ``"best"`` or ``"last"``.
    """

    epochs: int = 300
    batch_size: int | None = None
    lr: float | None = None
    warmup_epochs: float = 10.0
    weight_decay: float = 0.01
    grad_clip: float | None = None
    max_rotation: float = math.pi
    uniform_rotation: bool = False
    nodes_per_sample: int | None = None
    bary_ratio: float = 0.0
    bary_radius: float | None = None
    bary_max_neighbors: int = 16
    noise_std: float = 0.0
    noise_gamma: float = 0.1
    noise_walk: bool = False
    noise_shared: float = 0.0
    wall_noise: float = 0.0
    history_noise: float = 0.0
    speed_noise: float = 0.0
    speed_noise_steady: float = 0.0
    direction_noise: float = 0.0
    swell_noise: float = 0.0
    stretch_noise: float = 0.0
    time_scale: float = 1.0
    clot_mean_weight: float = 0.0
    wall_loss_weight: float = 0.0
    speedup_weight: float = 0.0
    speedup_fraction: float = 0.1
    average_weights: float = 0.0
    seed: int = 0
    split_seed: int = 0
    n_val: int = 2
    n_test: int = 1
    train_sims: tuple[str, ...] = ()
    val_sims: tuple[str, ...] = ()
    test_sims: tuple[str, ...] = ()
    skip_frames: int = 0
    rollout_steps: int = 1
    pushforward_steps: int = 0
    pushforward_guards: bool = False
    input_guards: bool = False
    guard_coherence: float = 0.2
    curriculum_epochs: float = 0.0
    frame: str = "global"
    wall_features: float = 0.0
    axis_features: float = 0.0
    follow_axis: float = 0.0
    lateral_hold: float = 0.0
    outlet_features: float = 0.0
    shape_features: float = 0.0
    clearance_features: float = 0.0
    section_features: float = 0.0
    centre_pull: float = 0.0
    centre_tolerance: float | str = 0.0
    rest_edges: bool = False
    start_speed: bool = False
    start_speed_noise: float = 0.0
    start_span: int = 1
    wall_signed: bool = False
    wall_clot_mean: bool = False
    history: int = 1
    stop_history_gradient: bool = False
    tiny: bool = False
    model_config: dict = dataclasses.field(default_factory=dict)
    checkpoint_every: int = 0
    select_by: str = "mse"
    init_from: str = ""
    init_which: str = "best"

    def __post_init__(self) -> None:
        for name in ("train_sims", "val_sims", "test_sims"):
            value = getattr(self, name)
            if isinstance(value, str) or not all(isinstance(v, str) for v in value):
                raise ConfigError(f"{name} must be a list of simulation names, got {value!r}")
            object.__setattr__(self, name, tuple(value))
        check_train_values(self)  # types, finiteness, ranges of every field
        if self.epochs < 1:
            raise ConfigError(f"epochs must be >= 1, got {self.epochs}")
        if self.batch_size is not None and self.batch_size < 1:
            raise ConfigError(f"batch_size must be >= 1, got {self.batch_size}")
        if self.max_rotation < 0:
            raise ConfigError(f"max_rotation must be >= 0 radians, got {self.max_rotation}")
        if self.bary_ratio < 0:
            raise ConfigError(f"bary_ratio must be >= 0, got {self.bary_ratio}")
        if self.nodes_per_sample is not None and self.nodes_per_sample < 1:
            raise ConfigError(f"nodes_per_sample must be >= 1, got {self.nodes_per_sample}")
        if self.select_by not in SELECT_BY:
            raise ConfigError(f"select_by must be one of {list(SELECT_BY)}, got "
                              f"{self.select_by!r}")
        if not isinstance(self.init_from, str):
            raise ConfigError(f"init_from must be a run directory, got {self.init_from!r}")
        if self.init_which not in CHECKPOINTS:
            raise ConfigError(f"init_which must be one of {list(CHECKPOINTS)}, got "
                              f"{self.init_which!r}")
        if self.frame not in FRAMES:
            raise ConfigError(f"frame must be one of {list(FRAMES)}, got {self.frame!r}")

    @property
    def window_length(self) -> int:
        """Frames per training window: the step's history, s_t, push-forward and loss steps."""
        return self.pushforward_steps + self.rollout_steps + self.history + 1

    def replace(self, **changes: Any) -> TrainConfig:
        """A copy with some fields changed; unknown fields raise :class:`ConfigError`."""
        return TrainConfig.from_dict({**self.to_dict(), **changes})

    def to_dict(self) -> dict:
        """JSON-ready dict."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> TrainConfig:
        """Inverse of :meth:`to_dict`; unknown keys raise :class:`ConfigError`."""
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ConfigError(f"unknown training option(s) {unknown}; known: {sorted(known)}")
        values = dict(d)
        if isinstance(values.get("max_rotation"), str):
            values["max_rotation"] = parse_angle(values["max_rotation"])
        return cls(**values)


@dataclasses.dataclass(frozen=True)
class RunConfig:
    """What defines a training run: the model, the dataset and the (resolved) training config.

    A run's ``config.json`` holds these three keys (plus data derived from the dataset:
    statistics, scaling, split, padding budget) and loads back with :func:`load_config_file`,
    so ``thrombojax train --config RUN/config.json --out NEW`` repeats the run. In a saved run
    ``train.batch_size`` and ``train.lr`` are resolved and ``train.model_config`` holds every
    field of the model config.

    Attributes:
        model: registry name of the surrogate.
        dataset: path of the dataset file.
        train: the :class:`TrainConfig`.
    """

    model: str
    dataset: str
    train: TrainConfig

    def to_dict(self) -> dict:
        """JSON-ready dict (the keys ``model``, ``dataset``, ``train`` of ``config.json``)."""
        return {"model": self.model, "dataset": self.dataset, "train": self.train.to_dict()}

    @classmethod
    def from_dict(cls, d: dict) -> RunConfig:
        """Read the run keys of a ``config.json`` dict (other keys are derived data)."""
        missing = [k for k in ("model", "dataset", "train") if k not in d]
        if missing:
            raise ConfigError(f"run config lacks {missing}")
        if not isinstance(d["train"], dict):
            raise ConfigError("run config: 'train' must be a JSON object")
        return cls(model=str(d["model"]), dataset=str(d["dataset"]),
                   train=TrainConfig.from_dict(d["train"]))


def load_config_file(path: str | pathlib.Path) -> TrainConfig | RunConfig:
    """Read a JSON config: a training config (keys of :class:`TrainConfig`) or a run's
    ``config.json`` (a :class:`RunConfig`: model, dataset and training config)."""
    path = pathlib.Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: training config file not found")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as err:
        raise ConfigError(f"{path}: not valid JSON: {err}") from err
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: a training config must be a JSON object")
    try:
        if "train" in data and "model" in data:
            return RunConfig.from_dict(data)
        return TrainConfig.from_dict(data)
    except ConfigError as err:
        raise ConfigError(f"{path}: {err}") from err
