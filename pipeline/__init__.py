"""pipeline: what each command does with files, the stages wired together.

- run, run_materials, run_steps, run_export: `run` (one material, several, the steps they share,
  --export); options: the option checks run, batch, render and segment share
- batch, batch_summary, dask_engine: `batch` as Dask tasks (and `evaluate --workers`)
- capture_jobs, render_jobs, infer_jobs, evaluate_job: the other commands' jobs
- report, report_figures: report.md, report.json and their figures
- label_files, albedo_files: the label and albedo-map files made for a capture

Every job takes values (never an argparse Namespace); flashbrdf.cli parses the command line.
"""
