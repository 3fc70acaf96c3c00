"""Qt-free models and services the widgets take in their constructors (no Qt here: import-linter checks it)."""
