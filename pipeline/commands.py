"""One function per `flashbrdf` sub-command; each takes the parsed arguments and returns 0.

Each stage's commands live in their own module (cmd_<stage>.py) so the stages stay apart; a
module that is not there yet means the command is not built yet.
"""

import importlib


def _delegate(module, name):
    def run(args):
        try:
            mod = importlib.import_module(f"pipeline.{module}")
        except ModuleNotFoundError as err:
            if err.name == f"pipeline.{module}":
                raise NotImplementedError(name) from None
            raise
        return getattr(mod, name)(args)
    run.__name__ = name
    return run


merl_slice = _delegate("cmd_brdf", "merl_slice")
train = _delegate("cmd_infer", "train")
infer = _delegate("cmd_infer", "infer")
evaluate = _delegate("cmd_infer", "evaluate")
extract = _delegate("cmd_extract", "extract")
segment = _delegate("cmd_segment", "segment")
render = _delegate("cmd_render", "render")
compare = _delegate("cmd_render", "compare")
run = _delegate("cmd_run", "run")
export = _delegate("cmd_export", "export")
batch = _delegate("batch", "batch")
import_diligent = _delegate("cmd_diligent", "import_diligent")
