"""The dashboard: one web page that shows and tunes the running loop (``jsc view``).

- :mod:`controls`: a parameter's descriptor → the control the page draws for it (pure);
- :mod:`series`: rolling windows of samples and their decimation to a point budget (pure);
- :mod:`graph`: the robots, plants and controllers found in the ROS graph (pure);
- :mod:`page`: the viser page (3D robots, plots, controls), no ROS;
- :mod:`~joint_space_control.nodes.dashboard`: the node that feeds the page from the graph
  and carries out what the page asks through the standard parameter services and the
  documented topics and services.
"""
