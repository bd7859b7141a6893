"""Datasets: one module per real dataset."""
