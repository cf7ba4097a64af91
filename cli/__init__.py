"""cli: the `flashbrdf` command. Parsing only: each cmd_* module builds its own subparser and hands
values (never the argparse Namespace) to one function of a stage or of flashbrdf.pipeline.

Stage code is imported inside each handler, so `flashbrdf --help` imports no stage.
"""
