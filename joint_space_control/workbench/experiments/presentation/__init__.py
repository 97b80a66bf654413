"""Figures and pages: what an experiment's runs and checks are shown as. :mod:`figures`
draws the plots a scenario names (``figures``: overlays, the §4 experiments' plots) from the
runs' recorded states and the checks' own numbers (``Outcome.numbers``), so that what is
drawn is what was checked; :mod:`sweep_figures` draws a sweep's ``sweep.png``, bars of a
1-D sweep or one heat map per metric of a grid with the theory's boundary on it;
:mod:`results` writes an experiment's ``summary.md`` and ``result.json`` and the results
page of many (``docs/results.md``, ``jsc experiment --report``). Pure: results in, files
out, no ROS; matplotlib is imported only when a figure is drawn, so loading a scenario never
pays for it.
"""
