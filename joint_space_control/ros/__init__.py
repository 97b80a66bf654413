"""The ROS 2 layer shared by every node (the controllers, the generator, the recorder and
``sim_bridge``): parameters declared with descriptors and validated, message checks at the
boundary, serialized message images, the control-path wait-set loop, loop statistics on
``/diagnostics``, the plant-mode watcher of ``trigger: auto``, and the ``main`` of every
executable. The executables themselves are in :mod:`joint_space_control.nodes`.
"""
