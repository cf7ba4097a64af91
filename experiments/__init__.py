"""experiments: the paper's protocols, apart from the stages: Table 1 (evaluate, eval3d, table1_report,
table1_files, runtime_plot), Table 2 (table2) and the external test set of `evaluate --test-dir`
(test_set). `flashbrdf evaluate` is their front door; nothing in the stages imports them."""
