"""The process runtime below every stage: argparse types (arguments), signal handling
(interrupts), output folders as transactions (folders) and the executors of parallel work
(executor). It imports only netgen.core; the command line that uses it is netgen.cli."""
