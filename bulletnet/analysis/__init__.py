"""What a recording means: capture score, metrics, stability limits, plots."""
