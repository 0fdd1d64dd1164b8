"""Rotation ensembles: one model rolled out on M rotated copies of a simulation, in one program.

A model trained with rotation augmentation (``--max-rotation``) is equivariant only as far as
it learned to be: the same simulation turned by a rotation ``R`` gives a slightly different
rollout once turned back. Averaging the M turned-back rollouts of fixed rotations is an
ensemble of one trained model (no extra training), the test-time counterpart of the
augmentation::

    rotations = fixed_rotations(4)                          # [4, 3, 3], the first the identity
    ens = rotation_rollout(step, params, stats, x0_prev, x0, node_type, mask, n_steps,
                           rotations=rotations)
    ens.mean, ens.spread, ens.members                       # as an EnsembleRollout

Member i runs the learned step on its copy: at every step the inputs are turned by ``R_i``
about the origin of the scaled coordinates (where the training augmentation turns its windows,
:func:`thrombojax.data.augment.rotate_window`) and the predicted positions turned back, so the
member's rollout, its guards (a :class:`~thrombojax.simulator.guard_set.GuardSet` as
``context``, unchanged) and its corrections are in the simulation's own coordinates. The
vessel's wall search a rollout makes once (:mod:`thrombojax.simulator.context`) holds node
indices ranked by distance, which a rotation does not change, so it serves every member.

:class:`RotatedStep` is that member step: a :class:`~thrombojax.simulator.step.LearnedStep`
whose parameters are ``{"inner": the model's variables, "rotation": [3, 3]}``
(:func:`rotated_params`); the identity gives the plain step's positions exactly (the inputs are
multiplied by the identity, exactly representable), and vessel and padded nodes keep their
positions exactly (copied, not turned twice). Its ``output`` (the normalised acceleration
a training loss compares) is that of the turned copy.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from thrombojax.errors import ConfigError
from thrombojax.models.registry import Surrogate
from thrombojax.simulator.ensemble import EnsembleRollout, ensemble_rollout, n_members
from thrombojax.simulator.rollout import as_step
from thrombojax.simulator.step import LearnedStep, StepOutput
from thrombojax.types import TargetStats, clot_mask

__all__ = ["RotatedStep", "fixed_rotations", "rotated_params", "rotation_members",
           "rotation_rollout"]


@dataclasses.dataclass(frozen=True)
class RotatedStep(LearnedStep):
    """A learned step run on a turned copy of its inputs (module docstring).

    ``params`` is ``{"inner": variables, "rotation": R [3, 3]}``; positions enter as ``x R^T``
    and leave as ``x R`` (row vectors). Every other field is the wrapped step's
    (:meth:`of`)."""

    @classmethod
    def of(cls, step: LearnedStep) -> RotatedStep:
        """The rotated form of ``step`` (same fields; a RotatedStep is returned as it is)."""
        if isinstance(step, RotatedStep):
            return step
        return cls(**{f.name: getattr(step, f.name) for f in dataclasses.fields(LearnedStep)})

    def __call__(self, params: dict, stats: TargetStats, x_prev: jax.Array, x_cur: jax.Array,
                 node_type: jax.Array, mask: jax.Array, *, train: bool = False,
                 rng: jax.Array | None = None, context: Any = None) -> StepOutput:
        rot = params["rotation"]
        out = super().__call__(params["inner"], stats, x_prev @ rot.T, x_cur @ rot.T,
                               node_type, mask, train=train, rng=rng, context=context)
        moving = clot_mask(node_type, mask)[:, None]  # the rigid rows stay exactly as they were
        return out.replace(positions=jnp.where(moving, out.positions @ rot, x_cur))

    def init(self, rng, x_prev, x_cur, node_type, mask) -> dict:
        """The wrapped step's variables with the identity rotation."""
        return {"inner": super().init(rng, x_prev, x_cur, node_type, mask),
                "rotation": jnp.eye(3, dtype=jnp.float32)}


def fixed_rotations(n: int, seed: int = 0) -> np.ndarray:
    """``[n, 3, 3]`` float32 rotation matrices: the identity first, then ``n - 1`` drawn
    uniformly (Haar measure: the Q factor of a Gaussian matrix, signs fixed, determinant +1)
    from ``numpy.random.default_rng(seed)``, so the same ``(n, seed)`` gives the same set."""
    if not isinstance(n, int | np.integer) or isinstance(n, bool) or n < 1:
        raise ConfigError(f"rotation ensemble: needs n >= 1 rotations, got {n!r}")
    rng = np.random.default_rng(seed)
    out = [np.eye(3)]
    while len(out) < n:
        q, r = np.linalg.qr(rng.standard_normal((3, 3)))
        q = q * np.sign(np.diag(r))[None, :]
        if np.linalg.det(q) < 0:
            q[:, 0] = -q[:, 0]
        out.append(q)
    return np.asarray(out, np.float32)


def _checked_rotations(rotations: Any) -> jax.Array:
    """``[R, 3, 3]`` float32 rotations from an int R (:func:`fixed_rotations`) or matrices,
    checked: a ConfigError for another shape or a matrix that is not a rotation."""
    if isinstance(rotations, int | np.integer) and not isinstance(rotations, bool):
        rotations = fixed_rotations(int(rotations))
    rotations = jnp.asarray(rotations, jnp.float32)
    if rotations.ndim != 3 or rotations.shape[1:] != (3, 3) or rotations.shape[0] < 1:
        raise ConfigError(f"rotation ensemble: rotations must be [M, 3, 3] with M >= 1, got "
                          f"{tuple(rotations.shape)}")
    ortho = jnp.abs(rotations @ jnp.swapaxes(rotations, 1, 2) - jnp.eye(3)).max()
    if not float(ortho) < 1e-4 or not bool((jnp.linalg.det(rotations) > 0).all()):
        raise ConfigError("rotation ensemble: every matrix must be a rotation (orthonormal, "
                          "determinant +1)")
    return rotations


def rotated_params(params: Any, rotations: Any) -> dict:
    """The stacked member parameters of one model's rotation ensemble: ``{"inner": params``
    repeated M times ``, "rotation": rotations [M, 3, 3]}`` (the leading member axis of
    :func:`thrombojax.simulator.ensemble.ensemble_rollout`). ``rotations``: ``[M, 3, 3]`` or
    an int M (:func:`fixed_rotations`)."""
    turned = _checked_rotations(rotations)
    m = turned.shape[0]
    inner = jax.tree.map(lambda x: jnp.broadcast_to(jnp.asarray(x), (m, *jnp.shape(x))), params)
    return {"inner": inner, "rotation": turned}


def rotation_members(params_stack: Any, rotations: Any) -> dict:
    """The member parameters of M models (leaves ``[M, ...]``, :func:`stack_params`) each on R
    rotations: ``[M * R]`` members, model-major (model i's copies are members ``i R .. i R + R -
    1``), for :class:`RotatedStep` in
    :func:`thrombojax.simulator.ensemble.ensemble_rollout`. ``rotations``: ``[R, 3, 3]`` or an
    int R (:func:`fixed_rotations`)."""
    turned = _checked_rotations(rotations)
    r = int(turned.shape[0])
    m = n_members(params_stack)
    inner = jax.tree.map(lambda x: jnp.repeat(jnp.asarray(x), r, axis=0), params_stack)
    return {"inner": inner, "rotation": jnp.tile(turned, (m, 1, 1))}


def rotation_rollout(
    model: Surrogate | LearnedStep,
    params: Any,
    stats: TargetStats,
    x0_prev: jax.Array,
    x0: jax.Array,
    node_type: jax.Array,
    mask: jax.Array,
    n_steps: int,
    *,
    rotations: Any,
    rollout_fn: Callable | None = None,
    context: Any = None,
    member_batch: int | None = None,
    guard_mean: bool = False,
) -> EnsembleRollout:
    """Roll one model out on M rotated copies of the start, turned back, in one program:
    :func:`~thrombojax.simulator.ensemble.ensemble_rollout` of :class:`RotatedStep` with
    :func:`rotated_params`.

    Args:
        model, params, stats: the surrogate (or its learned step), its variables, statistics.
        x0_prev, x0, node_type, mask, n_steps: as in
            :func:`thrombojax.simulator.ensemble.ensemble_rollout` (scaled coordinates).
        rotations: ``[M, 3, 3]`` rotation matrices (:func:`fixed_rotations`), or an int M
            (``fixed_rotations(M)``).
        rollout_fn, context, member_batch, guard_mean: as in ``ensemble_rollout`` (the guards
            act in the simulation's coordinates, on every member and, with ``guard_mean``, on
            the mean).
    Returns:
        The :class:`~thrombojax.simulator.ensemble.EnsembleRollout`, every member turned back.
    """
    return ensemble_rollout(RotatedStep.of(as_step(model)), rotated_params(params, rotations),
                            stats, x0_prev, x0, node_type, mask, n_steps, rollout_fn=rollout_fn,
                            context=context, member_batch=member_batch, guard_mean=guard_mean)
