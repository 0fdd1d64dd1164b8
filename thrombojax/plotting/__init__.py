"""Plotting helpers shared by every layer that draws: view boxes, cameras, wall subsets, atomic
picture writes (:mod:`.scene`) and readable value axes (:mod:`.ticks`).

It sits just above the data files (it writes pictures with :mod:`thrombojax.io.outputs`' atomic
writes), below the solver, training and evaluation, so the solver's dataset plot, the training
loss plot and the evaluation figures all use it.
"""
