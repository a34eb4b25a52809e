"""Package data: the KinDER paper's results (``paper_results.csv``), each baseline's paper
settings (``paper_settings.csv``) and our baselines' deviations from the paper
(``baseline_deviations.csv``)."""
