"""Studies that reproduce the seeds' figures and tables; each writes JSON and PNG."""
