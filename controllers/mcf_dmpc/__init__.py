"""Paper A (spec 000, "Cooperative Control of Virtually Coupled Train Sets through the Fusion of Multiple
Car-Following Models"): its control laws as pure controllers (numpy/osqp, no libsumo, no I/O).

Modules, in the order of the paper:

* :mod:`.spacing`    — Table I unit, desired spacing D^(e) (Eq. 5), safe spacing D^(s) (Eq. 6), the unit as
  :class:`~railsim.physics.vehicle.VehicleParams`;
* :mod:`.cf_models`  — enhanced IDM/CACC/FVD (Eq. 8, 10, 11–13) and the originals (Eq. 7, 9), vectorised;
* :mod:`.rollout`    — predecessor horizon from a broadcast plan, MCF rollout (Eq. 29), Eq. (2) predictions;
* :mod:`.cost`       — J^(DMPC) (Eq. 14–19) plus the Eq. (20) penalty;
* :mod:`.dmpc`       — the continuous DMPC baseline as a warm-started OSQP QP;
* :mod:`.opo`        — online parameter optimisation (Eq. 29–30);
* :mod:`.optim`      — MSMFO and the benchmark optimisers (Eq. 21–28; separate package);
* :mod:`.kernels`    — the rollout and J^(DMPC) compiled with numba (the optimisers' fitness);
* :mod:`.msmfo_jit`  — the default MSMFO fused with that fitness in one compiled call (same draws, same result);
* :mod:`.controller` — the registered controllers ``cf_idm``, ``cf_cacc``, ``cf_fvd``, ``mcf_dmpc``,
  ``opo_mcf_dmpc``, ``dmpc``;
* :mod:`.sim`, :mod:`.metrics` — a numpy closed-loop platoon runner and the paper's tracking metrics.

Importing this package registers the controllers.
"""

from controllers.mcf_dmpc import controller as _controller  # noqa: F401  (registers the controllers)
