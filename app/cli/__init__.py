"""The ``flexvox`` command line: one module per subcommand, registered in :mod:`app.cli.main`."""
