"""Demonstrations: collecting them with any agent, the project's datasets and their cards.

* ``collection.py``: collecting demonstrations in parallel and resumably, building datasets;
* ``specs.py``: the datasets ``make datasets`` collects (agent, arguments, counts, seeds);
* ``cards.py``: each dataset's ``README.md``, written from the data themselves.

Collection runs episodes with the evaluation runner (``kinder_bench.evaluation``); it uses
neither reporting nor the policy server. (The showcase run is ``kinder_bench/demo.py``.)
"""
