"""Recording and reading runs: which topics a bag holds, the disk budget, and the run summary."""
