"""Speed benchmarks, run as ``mjnav bench <name>``: ``throughput`` (environment and adapter steps/s),
``sim`` (NavSim build, reset and step times) and ``action_layer`` (region, mapping and MPC latencies)."""
