"""Inputs that may be JAX tracers (inside `jax.grad`, `jax.vmap`, `jax.jit`).

A simulation needs a few concrete numbers before it can trace anything (the grid, the
step count, whether the slab is plastic): `concrete_tree` recovers them from tracers
where JAX still holds them (the primal values under `jax.grad` / `jax.jvp`, all members
of a batch under `jax.vmap`) and returns None inside `jax.jit`, where only shapes are
known. `concrete_members` splits a `jax.vmap` batch into its members, for checks that
take one member at a time. `dtype_name` accepts every way of naming a float dtype.
"""

from __future__ import annotations

import contextlib
from typing import Any

import jax
import numpy as np

__all__ = [
    "concrete_members",
    "concrete_tree",
    "concrete_value",
    "dtype_name",
    "eager_if_concrete",
    "is_traced",
    "under_staging",
]


def is_traced(tree: Any) -> bool:
    """Whether any leaf of ``tree`` is a JAX tracer."""
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves(tree))


def under_staging() -> bool:
    """Whether the caller runs inside a staging transform (`jax.jit`, `equinox.filter_jit`,
    the body of `jax.lax.scan` / `jax.lax.map`, ...): there every JAX operation, even on
    concrete inputs, returns a tracer, so a run with concrete inputs must be evaluated
    eagerly (`jax.ensure_compile_time_eval`) to keep its concrete path. False under
    `jax.grad` and `jax.vmap`, which do not stage what does not depend on their inputs."""
    import jax.numpy as jnp

    return isinstance(jnp.zeros(()), jax.core.Tracer)


def eager_if_concrete(inputs: Any) -> contextlib.AbstractContextManager:
    """`jax.ensure_compile_time_eval` where ``inputs`` are concrete but the caller stages
    (`under_staging`: a run captured by, or static under, a jitted function), else a
    null context. A run that does not depend on the traced inputs is then evaluated
    once, while tracing, with its whole concrete path (checks, compiled chunks, events),
    and its result is a constant of the traced function."""
    if not is_traced(inputs) and under_staging():
        return jax.ensure_compile_time_eval()
    return contextlib.nullcontext()


def concrete_value(x: Any) -> Any:
    """The concrete value behind ``x``, or None if JAX does not hold one.

    ``x`` itself when it is not a tracer; the primal value under `jax.grad` / `jax.jvp`;
    the whole batch (every member, the batch axis included) under `jax.vmap`; None under
    `jax.jit` (and other staging transforms).
    """
    from jax._src import core

    for _ in range(64):  # nested transforms: one tracer level per iteration
        if not isinstance(x, core.Tracer):
            return x
        to_concrete = getattr(core, "to_concrete_value", None)
        value = to_concrete(x) if to_concrete is not None else None
        if value is not None:
            return value
        if hasattr(x, "primal"):  # forward-mode tracer (jax.jvp)
            x = x.primal
        elif hasattr(x, "val") and hasattr(x, "batch_dim"):  # jax.vmap tracer
            x = x.val
        else:
            return None
    return None


def concrete_tree(tree: Any) -> Any:
    """``tree`` with every leaf replaced by its concrete value (`concrete_value`), or None
    if some leaf has none (inside `jax.jit`)."""
    leaves, treedef = jax.tree.flatten(tree)
    values = [concrete_value(x) for x in leaves]
    if any(v is None for v in values):
        return None
    return jax.tree.unflatten(treedef, values)


def _unwrap(x: Any) -> tuple[Any, list[int]]:
    """The concrete value behind ``x`` (None inside `jax.jit`) and the batch axes that
    `jax.vmap` levels added to it, innermost level first."""
    from jax._src import core

    axes: list[int] = []
    for _ in range(64):
        if not isinstance(x, core.Tracer):
            return x, axes
        to_concrete = getattr(core, "to_concrete_value", None)
        value = to_concrete(x) if to_concrete is not None else None
        if value is not None:
            return value, axes
        if hasattr(x, "primal"):
            x = x.primal
        elif hasattr(x, "val") and hasattr(x, "batch_dim"):
            if isinstance(x.batch_dim, int):
                axes.append(x.batch_dim)
            x = x.val
        else:
            return None, axes
    return None, axes


def concrete_members(tree: Any) -> list[Any] | None:
    """The concrete values behind ``tree``, one tree per member of a `jax.vmap` batch
    (``[concrete_tree(tree)]`` when nothing is batched); None inside `jax.jit` and for
    nested `jax.vmap` batches (then only the runtime guards check the values)."""
    leaves, treedef = jax.tree.flatten(tree)
    values, axes = [], []
    for x in leaves:
        value, ax = _unwrap(x)
        if value is None or len(ax) > 1:
            return None
        values.append(value)
        axes.append(ax[0] if ax else None)
    sizes = {np.shape(v)[a] for v, a in zip(values, axes, strict=True) if a is not None}
    if len(sizes) > 1:
        return None
    if not sizes:
        return [jax.tree.unflatten(treedef, values)]
    pairs = [(v, a) if a is None else (np.asarray(v), a) for v, a in zip(values, axes, strict=True)]
    return [
        jax.tree.unflatten(treedef, [v if a is None else np.take(v, i, axis=a) for v, a in pairs])
        for i in range(sizes.pop())
    ]


def dtype_name(dtype: Any) -> str | None:
    """Canonical name (``"float32"``, ``"float64"``, ...) of a dtype given as a string, a
    numpy or JAX dtype or scalar type (``np.float64``, ``jnp.float64``,
    ``np.dtype("float64")``); None if it names no dtype."""
    try:
        return np.dtype(dtype).name
    except TypeError:
        return None
