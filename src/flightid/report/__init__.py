"""Reports: text tables, figures, HTML and JSON. Reads results; computes nothing new."""
