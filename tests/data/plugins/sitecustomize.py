# Put this folder on PYTHONPATH and every Python started (e.g. `.venv/bin/railsim validate`) registers the
# test-only controllers of railsim_test_controllers.py. Used by tests/unit/test_scenario_cli.py only.
import railsim_test_controllers  # noqa: F401
