"""Model-validation study on the real Pathfinder logs (issue 3 sec. 2).

``slip-estimator validate --out docs/validation.md`` (or ``python -m slip_estimator.validation
--out docs/validation.md``) regenerates ``docs/validation.md`` and its figures from the data:

1. both logs (``test17run``, ``s5t1``) are imported into a temporary folder
   (:func:`slip_estimator.pathfinder.import_pathfinder`; nothing is written into the repo but
   the report and the figures);
2. a sequence of model configurations, from the paper's model to ours, each adding ONE effect
   on top of the imported parameters (:data:`configs.CONFIGS`, A..F), is replayed through the
   node logic (:func:`slip_estimator.replay.replay_bag`) on both logs and on test17run with
   injected slip (real IMU, wheel speeds scaled inside windows, :func:`study.inject_wheel_slip`);
3. every run is evaluated with :func:`slip_estimator.report.load_run` and
   :func:`slip_estimator.evaluation.evaluate_run`, plus the residual statistics the node
   publishes on ``/diagnostics`` (NIS means, resets, recoveries) and the bias of the reported
   slip where the truth says low slip;
4. the evidence figures are computed from the same data, and the report says which metric
   rests on which truth (test17run RTK: everything; s5t1 single point: whole-run figures only).

Modules, compute apart from rendering (as evo's ``main_ape`` / ``main_res``):

configs   the configurations A..F and the study's fixed inputs
study     :func:`~study.run_study` -> :class:`~study.Study` (saved / loaded as JSON); cases run
          in parallel worker processes (``--jobs``, default 2), each a replay + evaluation
evidence  the figures measured from the logs and the core-level runs behind the statements
figures   the PNG figures (Agg)
markdown  the report: a template filled by short section functions, every number from the study
          (sections: the page and its general sections; sections_effects: evidence per effect;
          sections_evidence: the core-level evidence runs; tables: cells, tables, metric
          look-ups; verdicts: thresholds and the judgements drawn from the numbers)
cli       the ``slip-estimator validate`` shell
"""
