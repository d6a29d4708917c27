"""railsim: virtually coupled trains on SUMO rail networks.

Packages (docs/architecture.md): ``network`` builds worlds, ``railsim`` runs them, ``controllers`` decides,
``scenarios/`` describes. The public Python API mirrors the CLI: anything ``railsim`` does on the command
line is a call here (``railsim.scenario.load``, ``railsim.api.run``, ``network.build``).
"""

__version__ = "0.1.0"

from railsim import kernel_cache as _kernel_cache, native as _native

_kernel_cache.configure()  # before any kernel compiles: numba's cache keyed on the kernel sources
_native.activate()  # before any engine module loads: the compiled core when it is built and up to date
