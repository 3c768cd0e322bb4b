"""What toaster writes for people and other tools: exports, plots, MCAP recordings, RViz
markers."""
