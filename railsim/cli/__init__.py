"""The ``railsim`` command: the only argparse code, one module per command group (see :mod:`.main`)."""
