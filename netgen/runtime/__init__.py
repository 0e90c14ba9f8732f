"""The process runtime of the `netgen` command: the console entry, the command line and its error
boundary (cli), argparse types (arguments), signal handling (interrupts), output folders as
transactions (folders) and the executors of parallel work (executor). Only this package imports
argparse; entry and cli sit above every stage, the other modules below them."""
