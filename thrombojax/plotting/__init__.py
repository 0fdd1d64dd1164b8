"""Plotting helpers shared by every layer that draws: view boxes, cameras, wall subsets, atomic
picture writes (:mod:`.scene`) and readable value axes (:mod:`.ticks`).

A base layer: it imports only ``thrombojax.types``, numpy and matplotlib, so the solver's dataset
plot, the training loss plot and the evaluation figures all use it.
"""
