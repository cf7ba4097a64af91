"""One function per `flashbrdf` sub-command; each takes the parsed arguments and returns 0.

Each stage's commands live in their own module (cmd_<stage>.py) so the stages stay apart.
`commands.<name>` is that module's function, imported when first asked for: importing every stage
took 4.5 s against 1.1 s for `pipeline.cli` plus `cmd_brdf` alone (`python -X importtime`,
load 9 on 2 cores), a cost `flashbrdf merl-slice` and `--help` should not pay.
"""

import importlib

# sub-command function name -> the pipeline module that defines it
COMMANDS = {"merl_slice": "cmd_brdf", "train": "cmd_infer", "infer": "cmd_infer",
            "evaluate": "cmd_infer", "extract": "cmd_extract", "segment": "cmd_segment",
            "render": "cmd_render", "compare": "cmd_render", "run": "cmd_run",
            "export": "cmd_export", "batch": "batch", "import_diligent": "cmd_diligent",
            "import_colmap": "cmd_colmap"}


def __getattr__(name):
    if name not in COMMANDS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"flashbrdf.pipeline.{COMMANDS[name]}"), name)
