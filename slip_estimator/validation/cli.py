"""``slip-estimator validate``: parse arguments, run (or load) the study, write figures and
the report. The study, figures and Markdown modules are imported only when needed."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from slip_estimator.validation.configs import CONFIG_BY_KEY, DEFAULT_DATA_DIR, LOGS, say


def build_parser() -> argparse.ArgumentParser:
    """The command's options."""
    ap = argparse.ArgumentParser(
        prog='slip-estimator validate',
        description='Model-validation study on the real Pathfinder logs: replay configurations '
                    'A (paper) .. E (ours), evaluate, write a Markdown report with figures.',
        epilog='example: slip-estimator validate --out docs/validation.md --jobs 2')
    ap.add_argument('--out', required=True, type=Path, help='Markdown report to write')
    ap.add_argument('--fig-dir', type=Path,
                    help='figure folder (default: <out without .md>/, e.g. docs/validation/)')
    ap.add_argument('--data-dir', type=Path, default=DEFAULT_DATA_DIR,
                    help='folder with test17run.mat and s5t1.mat (default: %(default)s)')
    ap.add_argument('--work-dir', type=Path,
                    help='keep the imported bags here (default: a temporary folder, removed)')
    ap.add_argument('--configs', default=','.join(CONFIG_BY_KEY),
                    help='comma-separated configurations (default: %(default)s)')
    ap.add_argument('--logs', default=','.join(LOGS), help='comma-separated logs')
    ap.add_argument('--no-injected', action='store_true', help='skip the injected-slip runs')
    ap.add_argument('--jobs', type=int, default=2, help='worker processes (default 2)')
    ap.add_argument('--json', type=Path, help='also save the study (every result) as JSON')
    ap.add_argument('--from-json', type=Path,
                    help='render the report from a study saved with --json instead of running')
    return ap


def validate_main(argv: list[str] | None = None) -> int:
    """``slip-estimator validate --out docs/validation.md`` (argv without the subcommand)."""
    args = build_parser().parse_args(argv)
    configs = [c.strip().upper() for c in args.configs.split(',') if c.strip()]
    bad = [c for c in configs if c not in CONFIG_BY_KEY]
    if bad:
        print(f'slip-estimator validate: unknown configuration(s) {bad}', file=sys.stderr)
        return 2
    logs = [x.strip() for x in args.logs.split(',') if x.strip()]
    from slip_estimator.validation.study import Study, run_study

    if args.from_json:
        if not args.from_json.is_file():
            print(f'slip-estimator validate: {args.from_json} not found', file=sys.stderr)
            return 2
        study = Study.load(args.from_json)
    elif not args.data_dir.is_dir():
        print(f'slip-estimator validate: data folder {args.data_dir} not found', file=sys.stderr)
        return 2
    else:
        study = run_study(args.data_dir, args.work_dir, configs, logs, not args.no_injected,
                          max(1, args.jobs))
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        study.save(args.json)
    from slip_estimator.validation.figures import write_figures
    from slip_estimator.validation.markdown import render_markdown

    fig_dir = args.fig_dir or args.out.with_suffix('')
    figures = write_figures(study, fig_dir)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(render_markdown(study, figures, args.out))
    say(True, f'wrote {args.out} and {len(figures)} figure(s) in {fig_dir} '
        f'({study.wall_s:.0f} s)')
    return 0
