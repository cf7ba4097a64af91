"""files: bad input and safe output, below every stage; it imports nothing else of flashbrdf.

- errors: InputError (the contract's exit 2 and one stderr line naming the file or field)
- atomic: one file written whole or not at all (a temporary sibling, then a rename)
- outputs: no output over an input; folder outputs built aside and renamed (staged_output_dir)
- signals: Ctrl-C and SIGTERM end a command cleanly; native stderr held back on bad input
- threads: the thread budget ($FLASHBRDF_THREADS, a worker's share of the cores)
"""
