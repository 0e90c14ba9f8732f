"""Foundations every stage uses and that import nothing else of netgen: constants, errors, units,
text (names, comments), paths (file paths in simulator input), names (the name policy), files
(bounded reads, atomic writes), the TOML reader, templating, plots, the option declarations and
the one runner of external processes (process)."""
