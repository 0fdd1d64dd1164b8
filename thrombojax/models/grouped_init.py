"""Flax ``init`` with the weight draws grouped: one ``vmap``ed draw per initialiser and shape.

Flax draws every parameter array with its own key where the module creates it, and XLA
compiles each draw (threefry rounds, then the initialiser's transform) separately: ~150
instructions per array, so compiling the init of the study's MeshGraphNet (262 arrays) took
13.6 s and Erwin's (264) 20.7 s on a 2-core CPU, before the first training step
(``docs/performance.md``).

:func:`grouped_init` runs ``module.init`` with Flax's parameter creation deferred: each new
parameter takes its key from the same ``make_rng("params")`` call, in the same order, as in
Flax, but holds a zero placeholder of its shape while the module's forward pass is traced;
then the draws of the arrays that share an initialiser, its arguments, shape and dtype run as
one ``vmap`` over their keys, and the values replace the placeholders. A ``vmap``ed draw equals
the draws one by one bit for bit, so the parameters are those of ``module.init``
(``tests/test_grouped_init.py``). Parameters an initialiser returns boxed (Flax's
``AxisMetadata``) and those created inside a lifted transform (``nn.scan``, ``nn.custom_vjp``:
their keys belong to the transform's trace) are drawn in place, as Flax does. While it runs
it swaps Flax's ``Scope.param`` (restored on exit): do not initialise from two threads at once.
A module whose init computed another variable from a parameter's value would see the
placeholder; thrombojax's models do not (the bit-for-bit test covers each).
"""

from __future__ import annotations

import contextlib
import hashlib
from collections.abc import Callable, Iterator
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import traverse_util
from flax.core import meta
from flax.core.scope import Scope

__all__ = ["grouped_init"]


def _init_key(init_fn: Callable, args: tuple, kwargs: dict) -> Any:
    """What makes two draws the same function of their key: the initialiser (its code and
    closure values, so that ``truncated_normal(0.02)`` built twice groups) and its arguments;
    ``None`` when something is unhashable (the array is then drawn alone)."""
    try:
        cells = tuple(c.cell_contents for c in (init_fn.__closure__ or ()))
        code = getattr(init_fn, "__code__", init_fn)
        key = (code, cells, getattr(init_fn, "__defaults__", None), args,
               tuple(sorted(kwargs.items())))
        hash(key)
    except (TypeError, ValueError, AttributeError):
        return None
    return key


def _trace_of(x: Any) -> Any:
    """The trace a key belongs to (``None`` for a concrete key: arrays have no ``_trace``)."""
    return getattr(x, "_trace", None)


@contextlib.contextmanager
def _deferred(pending: list, outer: Any) -> Iterator[None]:
    """Within: new parameters whose key lives in the ``outer`` trace get zero placeholders and
    their draws are appended to ``pending``; those created inside a lifted transform (a key of
    an inner trace: ``nn.scan``, ``nn.custom_vjp``) are drawn in place, as Flax does."""
    original = Scope.param

    def param(self, name, init_fn, *init_args, unbox=True, **init_kwargs):
        if self.has_variable("params", name) or not self.is_mutable_collection("params"):
            return original(self, name, init_fn, *init_args, unbox=unbox, **init_kwargs)
        self.reserve(name, "params")
        lazy = _lazy_key(self)
        # make_rng's key (the counter is advanced already); a deferred draw only needs its shape
        rng = self.make_rng("params") if lazy is None else None
        shape = jax.eval_shape(lambda: init_fn(jax.random.fold_in(*lazy) if rng is None else rng,
                                               *init_args, **init_kwargs))
        if lazy is None or not isinstance(shape, jax.ShapeDtypeStruct) \
                or _trace_of(lazy[0]) is not outer:
            rng = jax.random.fold_in(*lazy) if rng is None else rng
            value = init_fn(rng, *init_args, **init_kwargs)
            self.put_variable("params", name, value)
            return meta.unbox(value) if unbox else value
        placeholder = jnp.zeros(shape.shape, shape.dtype)
        pending.append((tuple(self.path) + (name,), init_fn, init_args, init_kwargs, lazy, shape))
        self.put_variable("params", name, placeholder)
        return placeholder

    Scope.param = param
    try:
        yield
    finally:
        Scope.param = original


def _lazy_key(scope: Scope) -> tuple[Any, jax.Array] | None:
    """``scope.make_rng("params")`` split in two: the root key and the ``uint32`` that Flax
    folds into it (Flax's ``Scope.make_rng`` and ``_fold_in_static``, with its counter
    advanced the same way); ``None`` where Flax's internals are not those (then the caller
    uses ``make_rng``)."""
    try:
        from flax import config as flax_config
        from flax.core.scope import LazyRng
        if not scope.has_rng("params"):
            return None
        scope._check_valid()
        scope._validate_trace_level()
        count = scope.rng_counters["params"] + 1
        lazy = LazyRng.create(scope.rngs["params"], count)
        fix_separator = bool(flax_config.flax_fix_rng_separator)
    except (AttributeError, ImportError, KeyError):
        return None
    scope.rng_counters["params"] = count
    digest = hashlib.sha1()
    for x in lazy.suffix:
        if fix_separator:
            digest.update(b"\00")
        if isinstance(x, str):
            digest.update(x.encode("utf-8"))
        else:
            digest.update(x.to_bytes((x.bit_length() + 7) // 8, byteorder="big"))
    return lazy.rng, np.uint32(int.from_bytes(digest.digest()[:4], byteorder="big"))


def _keys(lazies: list) -> list:
    """The keys of ``(root, data)`` pairs: one ``vmap``ed ``fold_in`` per root key."""
    out: list = [None] * len(lazies)
    roots: dict[int, list[int]] = {}
    for i, (root, _) in enumerate(lazies):
        roots.setdefault(id(root), []).append(i)
    for idx in roots.values():
        root = lazies[idx[0]][0]
        data = jnp.asarray(np.array([lazies[i][1] for i in idx], np.uint32))
        keys = jax.vmap(lambda d, r=root: jax.random.fold_in(r, d))(data)
        for j, i in enumerate(idx):
            out[i] = keys[j]
    return out


def _draw(pending: list) -> dict[tuple, jax.Array]:
    """The values of the deferred parameters, one ``vmap`` per group."""
    keys = _keys([p[4] for p in pending])
    pending = [(*p[:4], key, p[5]) for p, key in zip(pending, keys, strict=True)]
    groups: dict[Any, list] = {}
    for i, (path, init_fn, args, kwargs, rng, shape) in enumerate(pending):
        key = _init_key(init_fn, args, kwargs)
        group = ("alone", i) if key is None else (key, shape.shape, str(shape.dtype))
        groups.setdefault(group, []).append((path, init_fn, args, kwargs, rng))
    values = {}
    for members in groups.values():
        _, init_fn, args, kwargs, _ = members[0]
        if len(members) == 1:
            values[members[0][0]] = init_fn(members[0][4], *args, **kwargs)
            continue
        keys = jnp.stack([m[4] for m in members])
        drawn = jax.vmap(lambda k, f=init_fn, a=args, kw=kwargs: f(k, *a, **kw))(keys)
        for j, member in enumerate(members):
            values[member[0]] = drawn[j]
    return values


def grouped_init(module: Any, rngs: Any, *args: Any, **kwargs: Any) -> dict:
    """``module.init(rngs, *args, **kwargs)`` with the weight draws grouped (module
    docstring): the same variables, a smaller program to compile."""
    pending: list = []
    leaves = jax.tree_util.tree_leaves(rngs)
    with _deferred(pending, _trace_of(leaves[0]) if leaves else None):
        variables = module.init(rngs, *args, **kwargs)
    variables = dict(variables)
    if not pending:
        return variables
    flat = traverse_util.flatten_dict(dict(variables["params"]))
    for path, value in _draw(pending).items():
        if path not in flat:
            raise RuntimeError(f"grouped_init: parameter {'/'.join(path)} was drawn but is not "
                               "in the module's variables")
        flat[path] = value
    variables["params"] = traverse_util.unflatten_dict(flat)
    return variables
