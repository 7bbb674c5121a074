"""Many runs: sweeps, studies (Monte Carlo, Sobol'), benchmarks, their reports."""
