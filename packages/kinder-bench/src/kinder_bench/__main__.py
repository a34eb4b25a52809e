"""``python -m kinder_bench`` runs the ``kinder`` command."""

from kinder_bench.cli.kinder import main

if __name__ == "__main__":
    main()
