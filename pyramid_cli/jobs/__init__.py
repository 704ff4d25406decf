"""What to compute, apart from where: the :class:`~pyramid_cli.jobs.work.Work` values the CLI, the API and the
runners share, with the rules that refuse or warn."""
