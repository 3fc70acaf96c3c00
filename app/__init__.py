"""flexvox's front ends: the ``flexvox`` command line (``flexvox_app.cli``) and the Qt application."""
