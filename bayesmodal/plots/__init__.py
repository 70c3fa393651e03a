"""Plotting functions: ``plot_*(result, *, ax=None, ...)`` returning the figure or axes.

Each module mirrors a library module (``plots.static`` for ``bayesmodal.static``, ...).
matplotlib is imported lazily by the functions, never at package import.
"""
