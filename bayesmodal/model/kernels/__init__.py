"""Compiled inner loops (numba) for the model extensions, batched across parameter sets.

Every nonlinear extension is written as the *exact* zero-order-hold discretisation of the
linear rig over a sub-step ``h = dt / n_sub`` plus extra force inputs ``f`` acting on the
carts (friction, cubic spring forces) or a switch between two exactly discretised linear
systems (backlash).  The linear part is therefore integrated without error and the only
approximation is in how ``f`` varies within a sub-step; with the extension switched off
``f = 0`` and the kernels reproduce the linear simulator to rounding error.  The
linear-input extensions (lag, delay, saturation) run an exact linear recursion whose
input is shifted and clipped per parameter set inside the kernel.

Batching follows ``bayesmodal.model._kernels``: the parameter sets ("lanes") are innermost and
contiguous, the lane count is a compile-time constant (a power of two up to
``MAX_WIDTH``), the kernel source is generated for each shape with the state unrolled into
scalars, and the branches of the hybrid models (stick, slip, contact) are written on local
scalars so that the compiler turns them into per-lane selects and vectorises across
parameter sets.  Lanes take every branch's cost, but SIMD across 8 lanes more than pays
for it.  The friction kernel takes each sample in one exact step and takes it again in
corrected sub-steps only for the lanes with an event in it, packed into full vectors
(see ``coulomb_run``).

Flat layouts (float64): parameters ``P (rows, width)``, state ``X (rows, width)`` updated in
place, outputs ``Y (N, n_out, width)`` with ``Y[k]`` the positions at ``t = k dt``.  The
driver ``run_batched`` packs per-lane arrays into these blocks, pads the batch with a
repeated valid lane, splits it into chunks of at most ``MAX_WIDTH`` lanes, and returns a
``(nb, N, n_out)`` view of the output buffer (no copy).

One module per kernel: ``linear_input`` (delay, saturation, motor lag, offsets),
``coulomb`` (stick-slip friction; the code of its steps in ``_coulomb_steps``), ``lugre``
(smooth friction), ``cubic`` (cubic springs), ``backlash`` (drive gap with impacts),
``expm`` (batched exponentials and exact zero-order holds), ``stop`` (the code of the
driven cart's end stop, which the cubic and friction kernels take); ``_codegen`` holds
the code generation they share, ``_exp`` the vectorisable exponentials.
"""

from ._codegen import MAX_WIDTH, padded_width, run_batched
from .backlash import backlash_run
from .coulomb import coulomb_run
from .cubic import cubic_run
from .expm import expm_batched, zoh
from .linear_input import linear_input_run
from .lugre import lugre_run

__all__ = ["MAX_WIDTH", "backlash_run", "coulomb_run", "cubic_run", "expm_batched",
           "linear_input_run", "lugre_run", "padded_width", "run_batched", "zoh"]
