"""Are two replay outputs the same estimates? Field by field, bit for bit.

``python -m slip_estimator.bench.identical BEFORE_BAG AFTER_BAG [--topics ...]`` compares the
slip (``/slip_estimator/slip``, ``/slip_estimator/slip_ratio``) and odometry
(``/slip_estimator/odometry``) messages of two output bags of ``slip-estimator replay``: the
same number of messages per topic, the same log times, and every field equal (floats compared
bit for bit, NaN equal to NaN). Exit status 0 when identical, 1 with the first differences
listed otherwise. A change that should not move any estimate (a faster decoder, a faster core)
is checked with it on a real log and a simulated drive, replayed before and after the change.
``--json BEFORE.json AFTER.json`` compares two figure files instead (``slip-estimator accuracy
--json``, ``bench --json``): every number, with the largest absolute difference and where.
"""
from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

ESTIMATE_TOPICS = ('/slip_estimator/slip', '/slip_estimator/slip_ratio',
                   '/slip_estimator/odometry')


def flat_fields(msg: Any, prefix: str = '') -> Iterator[tuple[str, Any]]:
    """(dotted field path, value) of every leaf field of a ROS message, lists of messages
    indexed (``status[0].values[2].value``)."""
    for name in msg.get_fields_and_field_types():
        value = getattr(msg, name)
        path = prefix + name
        if hasattr(value, 'get_fields_and_field_types'):
            yield from flat_fields(value, path + '.')
        elif isinstance(value, (list, tuple)) and value and hasattr(
                value[0], 'get_fields_and_field_types'):
            for i, item in enumerate(value):
                yield from flat_fields(item, f'{path}[{i}].')
        else:
            yield path, value


def _same(a: Any, b: Any) -> bool:
    """Equal, floats bit for bit (NaN equals NaN, 0.0 differs from -0.0)."""
    if isinstance(a, float) and isinstance(b, float):
        return a == b and math.copysign(1.0, a) == math.copysign(1.0, b) or (
            math.isnan(a) and math.isnan(b))
    if isinstance(a, (np.ndarray, list, tuple)) or type(a).__name__ == 'array':
        x, y = np.asarray(a), np.asarray(b)
        return x.shape == y.shape and x.tobytes() == y.tobytes()
    return a == b


def compare_messages(a: list[tuple[int, Any]], b: list[tuple[int, Any]], topic: str,
                     limit: int = 10) -> list[str]:
    """Differences (at most ``limit``) between two lists of (log time ns, message)."""
    out = []
    if len(a) != len(b):
        out.append(f'{topic}: {len(a)} messages vs {len(b)}')
    for k, ((ta, ma), (tb, mb)) in enumerate(zip(a, b)):
        if ta != tb:
            out.append(f'{topic}[{k}]: log time {ta} vs {tb}')
        fb = dict(flat_fields(mb))
        for path, va in flat_fields(ma):
            if path not in fb or not _same(va, fb[path]):
                out.append(f'{topic}[{k}].{path}: {va!r} vs {fb.get(path, "<missing>")!r}')
        if len(out) >= limit:
            break
    return out[:limit]


def compare_bags(before: str | Path, after: str | Path,
                 topics: tuple[str, ...] = ESTIMATE_TOPICS, limit: int = 10
                 ) -> tuple[dict[str, int], list[str]]:
    """(messages compared per topic, differences) between two replay output bags."""
    from slip_estimator.bagio import read_messages

    def load(path: str | Path) -> dict[str, list[tuple[int, Any]]]:
        out: dict[str, list[tuple[int, Any]]] = {t: [] for t in topics}
        for m in read_messages(path, set(topics)):
            out[m.topic].append((m.log_time_ns, m.msg))
        return out

    a, b = load(before), load(after)
    diffs: list[str] = []
    for topic in topics:
        diffs += compare_messages(a[topic], b[topic], topic, limit - len(diffs))
        if len(diffs) >= limit:
            break
    return {t: len(a[t]) for t in topics}, diffs


def compare_json(a: Any, b: Any, path: str = '') -> tuple[int, float, str, list[str]]:
    """(numbers compared, largest absolute difference, where, other differences) between two
    decoded JSON documents; NaN equals NaN."""
    if isinstance(a, dict) and isinstance(b, dict):
        parts = [compare_json(a[k], b[k], f'{path}.{k}') for k in a if k in b]
        other = [f'{path}: keys {sorted(set(a) ^ set(b))} in one only'] if set(a) != set(b) \
            else []
    elif isinstance(a, list) and isinstance(b, list):
        parts = [compare_json(x, y, f'{path}[{i}]') for i, (x, y) in enumerate(zip(a, b))]
        other = [f'{path}: {len(a)} items vs {len(b)}'] if len(a) != len(b) else []
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)) \
            and not isinstance(a, bool) and not isinstance(b, bool):
        nan_a, nan_b = math.isnan(a), math.isnan(b)
        return 1, abs(a - b) if not (nan_a or nan_b) else 0.0 if nan_a and nan_b else math.inf, \
            path, []
    else:
        return 0, 0.0, '', [] if a == b else [f'{path}: {a!r} vs {b!r}']
    n = sum(p[0] for p in parts)
    worst = max(parts, key=lambda p: p[1], default=(0, 0.0, '', []))
    return n, worst[1], worst[2], other + [o for p in parts for o in p[3]]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog='python -m slip_estimator.bench.identical',
        description='Compare the slip and odometry messages of two replay output bags field '
                    'by field, bit for bit.')
    parser.add_argument('before', type=Path)
    parser.add_argument('after', type=Path)
    parser.add_argument('--topics', nargs='+', default=list(ESTIMATE_TOPICS))
    parser.add_argument('--json', action='store_true',
                        help='compare two JSON figure files instead of two bags')
    args = parser.parse_args(argv)
    if args.json:
        import json
        n, worst, where, other = compare_json(json.loads(args.before.read_text()),
                                              json.loads(args.after.read_text()))
        print(f'{n} numbers compared, largest absolute difference {worst!r}'
              + (f' ({where})' if worst else '') + f'; {len(other)} other differences')
        for line in other[:10]:
            print('  ' + line)
        return 0 if worst == 0.0 and not other else 1
    from slip_estimator.bagio import BagError
    try:
        counts, diffs = compare_bags(args.before, args.after, tuple(args.topics))
    except BagError as exc:
        print(f'identical: {exc}', file=sys.stderr)
        return 2
    summary = ', '.join(f'{t} {n}' for t, n in counts.items())
    if diffs:
        print(f'DIFFERENT ({summary}):\n  ' + '\n  '.join(diffs))
        return 1
    print(f'identical: {summary} messages, every field bit for bit')
    return 0


if __name__ == '__main__':
    sys.exit(main())
