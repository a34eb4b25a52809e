"""Reporting: tables, the paper comparison, the HTML page and the results doc, from run directories.

* ``report.py``: the results table (markdown, CSV, plot) of a set of run directories;
* ``paper.py``: our results beside the paper's (Table II's layout), and the paper's protocol;
* ``html_report.py``: one self-contained HTML page for a set of runs;
* ``results_doc.py``: ``docs/results.md`` from the committed run summaries.

Reporting reads what evaluation wrote (``kinder_bench.evaluation``); it uses neither the
demonstrations nor the policy server.
"""
