"""A run's record: the trace recorder (``trace.csv``) and the figures drawn from a trace."""
