"""The learned simulator: the one learned step and everything that acts on it.

- :mod:`.step`: the learned step (inputs -> graph -> model -> denormalise -> integrate).
- :mod:`.previous`: the frames before t the step reads (``x_prev``: its history, and the clot's
  rest state with ``rest_edges``), taken from a trajectory and carried through a rollout.
- :mod:`.context`: what a rollout computes once for every step (the rigid vessel's wall search).
- :mod:`.features`: the extra node features of the step's input (history, wall, vessel axis,
  outlet, clot shape), in their order.
- :mod:`.rollout`: the step in a ``lax.scan`` (rollouts, the k-step loss).
- :mod:`.wall`, :mod:`.wall_build`: the rigid vessel wall as a pytree (triangles, or nodes and
  normals) and its exact nearest-point query; built on the host from a dataset frame.
- :mod:`.guards`: physics guards on a step's output (containment in the wall, coherence of the
  clot's shape, edge-length relaxation), each returning how far it moved every node.
- :mod:`.walls`: per-node input features from the wall and rest-state edge features
  (the model's own, for ``rest_edges``: ``thrombojax.models.meshgraphnet.edge_features``).
- :mod:`.ensemble`, :mod:`.committee`, :mod:`.rotations`: many rollouts in one compiled program
  (M models, perturbed starts, a committee fed its mean, one model on rotated copies).

Training losses, evaluation and benchmarks call :func:`thrombojax.simulator.step.make_step` and
never rebuild the step.
"""
