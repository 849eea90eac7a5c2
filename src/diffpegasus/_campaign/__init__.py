"""Campaigns: the resumable Monte Carlo comparison, over devices, processes and hosts."""
