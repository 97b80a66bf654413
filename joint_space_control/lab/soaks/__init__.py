"""``jsc soak``: the realtime loop over minutes or an hour (``soak``), with a fault
injected every minute (``fault_schedule``, ``fault_soak``), judged from its bags and logs
(``soak_metrics``, ``fault_timeline``, ``fault_metrics``, ``loop_digest``, ``node_logs``,
``fault_figures``)."""
