"""Speed benchmarks, run as ``mjnav bench <name>``: ``throughput`` (environment and adapter steps/s),
``collect`` (PPO collection steps/s and its phases for 1, 2, ... workers),
``sim`` (NavSim build, reset and step times) and ``action_layer`` (region, mapping and MPC latencies)."""
