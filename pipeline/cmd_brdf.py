"""`flashbrdf merl-slice`: the theta_d = 0 slice of a MERL table, as slice.csv."""

import os

from flashbrdf.brdf.merl import read_merl
from flashbrdf.brdf.views import check_flash_slice, flash_slice, write_slice_csv
from flashbrdf.files.outputs import check_outputs


def merl_slice(args):
    check_outputs(inputs=[args.brdf], outputs=[args.out])
    table = read_merl(args.brdf)
    rho, n = flash_slice(table)
    check_flash_slice(rho, args.brdf)  # a slice of 90 empty bins, which infer and run refuse
    write_slice_csv(args.out, rho, n, comments=[
        f"flashbrdf merl-slice {os.path.basename(args.brdf)}",
        "theta_d = 0 slice: mean over the valid phi_d bins of theta_d bin 0; n = phi_d bins used"])
    return 0
