"""Plots (matplotlib, Agg backend): figures written as PNG files. Plotting is I/O, so it lives here, not in
``controllers/`` (which stays pure). One module per figure family: :mod:`railsim.report.plots.paper002` reproduces
Paper C's Fig. 3–6 from a numpy reference log or an engine run.
"""
