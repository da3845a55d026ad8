"""Data: ground-truth simulation of scenarios, HDF5 data sets and their summaries."""
