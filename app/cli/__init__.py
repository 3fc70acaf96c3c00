"""The ``flexvox`` command line: one module per subcommand, registered in :mod:`flexvox_app.cli.main`."""
