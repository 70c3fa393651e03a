"""What the model gets wrong: effects, residual checks and the diagnosis that links them.

Three parts, one workflow:

``checks``
    Residual diagnostics of a fitted model (whiteness, spectrum, amplitude dependence,
    stick near velocity reversals, input correlation, decay, gain per record, ...): each
    returns a statistic, a calibrated null and the locations where the residual deviates.
``effects``
    The catalogue of model extensions (friction laws, input offset, dead band, saturation,
    lag, delay, backlash, cubic springs, amplitude-dependent gain) and their combinations,
    each a frozen description with priors and a compiled simulator (``kernels``).
``diagnosis``
    The workflow ``diagnose``: run the checks, rank the candidate effects, fit the best one,
    check again on the extended model.

``kernels`` holds the compiled (numba) simulators the effects run on.

Import from the parts, e.g. ``from bayesmodal.discrepancy.diagnosis import diagnose`` or
``from bayesmodal.discrepancy.effects import get_extension``.
"""
