"""flexvox's front ends: the ``flexvox`` command line (``app.cli``) and the Qt application."""
