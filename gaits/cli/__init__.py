"""nhgait.gaits.cli — the ``nhgait`` command: :mod:`.main` (entry point, exit statuses) and one
module per subcommand (:mod:`.derive`, :mod:`.simulate`, :mod:`.reproduce`, :mod:`.plan`,
:mod:`.sweep`; ``nhgait bench`` is :mod:`nhgait.gaits.bench.command`)."""
