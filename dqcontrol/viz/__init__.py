"""Viewing runs: the Meshcat viewer (live and replay) and the thesis-style figures.

- :mod:`dqcontrol.viz.meshcat_viewer` — the robot of the URDF in the browser (Pinocchio's
  ``MeshcatVisualizer``): live during a run, or a self-contained HTML replay of a run log;
- :mod:`dqcontrol.viz.figures` — matplotlib figures of a run and comparisons of runs.

The sub-modules are imported on demand (``from dqcontrol.viz.figures import plot_run``), so
importing :mod:`dqcontrol` never loads matplotlib or meshcat.
"""
