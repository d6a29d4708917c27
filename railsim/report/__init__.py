"""Reports, exports and plots of finished runs and sweeps (reads run folders through :mod:`railsim.analysis`)."""
