"""Flight logs: the one CSV + sidecar format, FVSysID-style ASCII files, column maps
for logs from anywhere, and the plausibility checks every load runs."""
