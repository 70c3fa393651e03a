"""Experimental modal analysis (lecture 11): modal parameters from measured FRFs and IRFs.

These methods use only input/output data, never the physical rig model, so they are an
independent check of the model-based identification.

FRF estimation (:mod:`.frf`; the signal tools in :mod:`.excitation`, :mod:`.irf`,
:mod:`.spectra`):

- :func:`welch_frf` -- H1/H2 and coherence from Welch-averaged spectra;
- :func:`pulse_frf` -- the same over the pulse-to-pulse transients of a pulse train;
- :func:`frf_from_experiment` -- chooses between them and :func:`impact_frf` for an
  ``Experiment`` (:mod:`.record_frf`, :func:`choose_frf_method`: a hammer test when the
  input is a force of isolated hits, :func:`is_impact_train`); step records through their
  increments (:func:`step_increments`);
- :func:`impulse_response` -- IRF by inverse FFT; :func:`free_decay_segments`;
- :func:`spectrum`, :func:`spectrogram`, :func:`band_coherence`, :func:`peak_prominence`.

FRF forms (:mod:`.forms`): receptance, mobility or accelerance from the sensor kind;
:func:`to_receptance`, :func:`receptance_estimate` (residues in receptance units, mode
shapes from mixed sensors).  Hammer tests (:mod:`.impact`): :func:`find_impacts` (refuses
a double impact), :func:`force_window`, :func:`impact_frf` (force and exponential
windows, H1/H2/Hv over the hits), :func:`correct_exponential_window`.

Modal parameter fits (one module each):

- :func:`circle_fit`, :func:`circle_fit_modes` -- single-mode circle fit (11b);
- :func:`multimode_fit` -- frequency-domain fit with residual mass and flexibility (11c);
- :func:`lsce`, :func:`lsce_frf`, :func:`error_curve`, :func:`stabilization_diagram` --
  least-squares complex exponential with several IRFs (11d);
- :func:`tfest` -- rational (transfer-function) least-squares fit of a chosen order;
- :func:`pick_peaks` -- first estimates from the FRF peaks;
- :func:`mac`, :func:`mac_estimates` -- Modal Assurance Criterion.

Every fit returns a frozen dataclass holding a :class:`ModalEstimate` (natural
frequencies, damping ratios, poles, residues, mode shapes normalised on cart 1 and an
``identified`` flag per mode).  :func:`identify` runs a method on an ``Experiment``.

Test structures: :class:`CantileverBeam` (lecture's 36-DOF beam) and
:func:`lecture_irfs` (lecture's three-mode LSCE example).  Plots are in
:mod:`bayesmodal.plots.ema`.
"""

from .analyze import METHODS, EMAResult, check_resonances, default_band, identify
from .beam import CANTILEVER_BETA_L, CantileverBeam
from .circle import CircleFit, CircleFitModes, circle_fit, circle_fit_modes, fit_circle
from .examples import LECTURE_POLES, LECTURE_SHAPES, ModalSystem, lecture_irfs, lecture_system
from .excitation import (
    free_decay_segments,
    is_impact_train,
    is_pulse_train,
    is_step_input,
    pulse_segments,
    step_increments,
)
from .forms import FRF_FORMS, form_units, orders_of, receptance_estimate, to_receptance
from .frf import (
    FRF,
    band_coherence,
    peak_prominence,
    pulse_frf,
    welch_frf,
    zoh_factor,
)
from .impact import (
    Impacts,
    correct_exponential_window,
    find_impacts,
    force_window,
    impact_frf,
)
from .irf import IRF, frequency_grid, impulse_response
from .lsce import (
    ErrorCurve,
    LSCEResult,
    StabilizationDiagram,
    error_curve,
    lsce,
    lsce_frf,
    stabilization_diagram,
)
from .mac import mac, mac_estimates
from .multimode import MultiModeFit, modal_basis, multimode_fit
from .peaks import Peaks, mode_indicator, pick_peaks
from .record_frf import FRF_METHODS, choose_frf_method, frf_from_experiment
from .result import ModalEstimate, match_modes, modal_estimate, normalise_shapes
from .spectra import Spectrogram, Spectrum, spectrogram, spectrum
from .tfest import TFEstimate, tfest

__all__ = [
    "METHODS",
    "EMAResult",
    "check_resonances",
    "default_band",
    "identify",
    "CANTILEVER_BETA_L",
    "CantileverBeam",
    "CircleFit",
    "CircleFitModes",
    "circle_fit",
    "circle_fit_modes",
    "fit_circle",
    "LECTURE_POLES",
    "LECTURE_SHAPES",
    "ModalSystem",
    "lecture_irfs",
    "lecture_system",
    "FRF",
    "IRF",
    "Spectrogram",
    "Spectrum",
    "band_coherence",
    "free_decay_segments",
    "frequency_grid",
    "FRF_METHODS",
    "choose_frf_method",
    "frf_from_experiment",
    "impulse_response",
    "is_impact_train",
    "is_pulse_train",
    "is_step_input",
    "peak_prominence",
    "pulse_frf",
    "pulse_segments",
    "spectrogram",
    "spectrum",
    "step_increments",
    "welch_frf",
    "zoh_factor",
    "FRF_FORMS",
    "form_units",
    "orders_of",
    "receptance_estimate",
    "to_receptance",
    "Impacts",
    "correct_exponential_window",
    "find_impacts",
    "force_window",
    "impact_frf",
    "ErrorCurve",
    "LSCEResult",
    "StabilizationDiagram",
    "error_curve",
    "lsce",
    "lsce_frf",
    "stabilization_diagram",
    "mac",
    "mac_estimates",
    "MultiModeFit",
    "modal_basis",
    "multimode_fit",
    "Peaks",
    "mode_indicator",
    "pick_peaks",
    "ModalEstimate",
    "match_modes",
    "modal_estimate",
    "normalise_shapes",
    "TFEstimate",
    "tfest",
]
