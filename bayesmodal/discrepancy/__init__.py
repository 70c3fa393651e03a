"""What the model gets wrong: residual checks and the diagnosis that links them to the
effects of ``bayesmodal.model.effects``.

Two parts, one workflow:

``checks``
    Residual diagnostics of a fitted model (whiteness, spectrum, amplitude dependence,
    stick near velocity reversals, input correlation, decay, gain per record, ...): each
    returns a statistic, a calibrated null and the locations where the residual deviates.
``diagnosis``
    The workflow ``diagnose``: run the checks, rank the candidate effects, fit the best one,
    check again on the extended model.

The effects themselves (the catalogue of model extensions and their compiled simulators)
live in ``bayesmodal.model.effects``, their fits in ``bayesmodal.fit``.

Import from the parts, e.g. ``from bayesmodal.discrepancy.diagnosis import diagnose``.
"""
