"""Paper B (Wang, Xing, Wang 2024): stability-enhanced MPC for automatic train operation, and its baselines.

Modules: :mod:`.model` (multi-point controller model, Eq. (4)–(9)), :mod:`.qp` (condensed OSQP programme),
:mod:`.sempc` (terminal ingredients, SEMPC), :mod:`.mpc` (MPC-A/B), :mod:`.afsmc`, :mod:`.pid`,
:mod:`.reference` (speed–distance and time profiles), :mod:`.core` (stop/hold supervisor), :mod:`.sim`
(closed-loop scenarios A/B/C on :mod:`railsim.physics.multipoint`), :mod:`.ato_role` (the ``ato``-role factories).

Importing the package registers ``sempc``, ``mpc``, ``afsmc`` and ``pid_ato``.
"""

from controllers.ato_mpc import ato_role  # noqa: F401  (registers the controllers)
