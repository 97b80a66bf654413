"""The lab: what a maintainer proves the package with, not what a user runs.

``bench`` (``jsc bench``: the loop's speed, over ROS and in process, realtime under load,
the dashboard beside it), ``soaks`` (``jsc soak``: the realtime loop for an hour, with a
fault injected every minute, judged from its bags) and ``discretisation`` (the plant's
discretisation error on both engines). It depends on the product and the workbench; nothing
there depends on it.
"""
