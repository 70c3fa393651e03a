"""Classical modal analysis of the rig (report sections 3 and 4).

Every function works on one system or, through leading batch dimensions, on thousands of
posterior samples at once.

Undamped modes, three ways (they agree to rounding):

- :func:`undamped_modes` -- generalised symmetric eigenproblem ``(K - omega^2 M) u = 0``;
- :func:`rayleigh_modes` -- stationary points of the Rayleigh quotient (no eigen-solver);
  :func:`rayleigh_quotient` evaluates it on grids;
- :func:`matrix_iteration` -- power iteration with deflation on ``D = K^-1 M``.

Damping and response:

- :func:`modal_matrices` -- ``U^T M U``, ``U^T C U``, ``U^T K U`` and damping coupling;
- :func:`proportional_modal_damping` -- ``zeta`` and damped frequency for ``C = ca M + cb K``;
- :func:`complex_modes`, :func:`state_space_modes` -- eigenvalues of the state matrix for
  any damping;
- :func:`transfer_function` -- X/V or X/F on a frequency grid;
- :func:`mac` -- Modal Assurance Criterion;
- :func:`modal_summary` -- a JSON-ready dict for one parameter vector;
- :func:`modal_report` -- the whole classical analysis of one parameter vector (CLI).

Plots are in :mod:`bayesmodal.plots.modal`.
"""

from .complex_modes import ComplexModes, complex_modes, state_space_modes
from .damping import ModalDamping, ModalMatrices, modal_matrices, proportional_modal_damping
from .frf import transfer_function
from .iteration import ConvergenceError, IterationModes, matrix_iteration
from .mac import mac
from .rayleigh import RayleighModes, rayleigh_gradient, rayleigh_modes, rayleigh_quotient
from .summary import modal_report, modal_summary
from .undamped import UndampedModes, orthogonality_error, undamped_modes

__all__ = [
    "UndampedModes",
    "undamped_modes",
    "orthogonality_error",
    "RayleighModes",
    "rayleigh_modes",
    "rayleigh_quotient",
    "rayleigh_gradient",
    "IterationModes",
    "matrix_iteration",
    "ConvergenceError",
    "ModalMatrices",
    "modal_matrices",
    "ModalDamping",
    "proportional_modal_damping",
    "ComplexModes",
    "complex_modes",
    "state_space_modes",
    "transfer_function",
    "mac",
    "modal_summary",
    "modal_report",
]
