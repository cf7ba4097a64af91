"""pipeline: the `flashbrdf` command, which wires the stages together.

It is the only package that imports more than one stage.
"""
