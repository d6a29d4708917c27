"""Paper E (spec 004, Wang et al. 2021): cooperative-game virtual coupling at junctions, as a pure library.

* :mod:`.model`     — parameters, paths, the distance-segment acceleration encoding, exact vectorised rollout,
  the cost ``f_c`` (Eqs. 17–26) and the constraint violations (Eqs. 36–39, 2–3);
* :mod:`.game`      — players, queue coalitions, marginal costs and Shapley values (Eqs. 24–33), by enumeration
  and in closed form;
* :mod:`.pso`       — improved PSO (spec §3.6) and plain PSO (§4.2);
* :mod:`.baselines` — naive strategy 1 (closest first) and 2 (fastest first), §4.2;
* :mod:`.planner`   — the online planner's pure core: states in, :class:`~.planner.JunctionPlan` out, re-plan;
* :mod:`.simulate`  — a time-stepped numpy simulator of a plan, metrics, and the Table 3 comparison.

No libsumo, no file I/O; randomness only from a caller's ``numpy.random.Generator``.
"""
