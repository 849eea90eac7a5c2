"""Reports a person opens: figures and markdown tables."""
