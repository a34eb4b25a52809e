"""Package data: the KinDER paper's results (``paper_results.csv``)."""
