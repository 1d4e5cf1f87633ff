"""The README is the front door, docs/ holds the rest: short, linked, in step with the code."""
import dataclasses
import re
from pathlib import Path

import pytest

from slip_estimator.core.params import RENAMED_PARAMETERS, Params
from slip_estimator.ros.topics import (OUTPUT_TYPES, TOPIC_IMU, TOPIC_JOINT_STATES,
                                       TOPIC_WHEEL_ODOMETRY)

REPO = Path(__file__).resolve().parents[2]
README = REPO / 'README.md'
PAGES = [README] + sorted((REPO / 'docs').glob('*.md'))
README_MAX_LINES = 220
INPUT_TOPICS = (TOPIC_IMU, TOPIC_JOINT_STATES, TOPIC_WHEEL_ODOMETRY)

LINK = re.compile(r'!?\[[^\]]*\]\(([^)\s]+)\)')
FENCE = re.compile(r'^```.*?^```', re.S | re.M)


def prose(path: Path) -> str:
    """The page without its fenced code blocks (a link there is not rendered)."""
    return FENCE.sub('', path.read_text())


def anchor(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r'[`*_]', '', heading.strip().lower())
    return re.sub(r'[^\w\- ]', '', text).replace(' ', '-')


def anchors(path: Path) -> set[str]:
    return {anchor(m.group(1)) for m in re.finditer(r'^#+\s+(.*)$', prose(path), re.M)}


def relative_links(path: Path) -> list[str]:
    return [t for t in LINK.findall(prose(path)) if not re.match(r'[a-z]+:', t)]


def test_readme_fits_two_screens_and_a_bit():
    assert len(README.read_text().splitlines()) <= README_MAX_LINES


@pytest.mark.parametrize('page', PAGES, ids=lambda p: p.relative_to(REPO).as_posix())
def test_every_relative_link_resolves(page):
    broken = []
    for target in relative_links(page):
        file, _, frag = target.partition('#')
        dest = (page.parent / file).resolve() if file else page
        if not dest.exists():
            broken.append(f'{target}: no such file')
        elif frag and dest.suffix == '.md' and frag not in anchors(dest):
            broken.append(f'{target}: no heading #{frag} in {dest.name}')
    assert not broken, broken


def test_the_link_checker_sees_a_broken_file_and_a_broken_anchor(tmp_path):
    page = tmp_path / 'p.md'
    (tmp_path / 'q.md').write_text('# Known limit\n')
    page.write_text('[a](q.md#known-limit) [b](q.md#nope) [c](gone.md) [d](https://x.org)\n'
                    '```\n[e](in-code.md)\n```\n')
    assert relative_links(page) == ['q.md#known-limit', 'q.md#nope', 'gone.md']
    assert anchors(tmp_path / 'q.md') == {'known-limit'}


def test_readme_figure_is_small_and_committed():
    images = [t for t in LINK.findall(prose(README)) if t.endswith('.png')]
    assert images, 'the README shows one figure from the demo'
    for image in images:
        assert (REPO / image).stat().st_size < 200 * 1024, image


def test_readme_and_node_page_name_every_topic_of_the_node():
    readme, node = README.read_text(), (REPO / 'docs' / 'node.md').read_text()
    for topic in (*INPUT_TOPICS, *OUTPUT_TYPES):
        assert f'`{topic}`' in readme, topic
        assert f'`{topic}`' in node, topic


def test_readme_parameter_table_names_real_parameters():
    table = prose(README).split('## Main parameters', 1)[1].split('\n## ', 1)[0]
    names = re.findall(r'`([a-z_]+)`', ''.join(l.split('|')[1] for l in table.splitlines()
                                                if l.startswith('| `')))
    fields = {f.name for f in dataclasses.fields(Params)}
    assert names and not set(names) - fields, set(names) - fields


def test_node_page_names_every_renamed_parameter():
    node = (REPO / 'docs' / 'node.md').read_text()
    missing = [old for old in RENAMED_PARAMETERS if f'`{old}`' not in node]
    assert not missing, missing


def test_layout_page_lists_every_module():
    layout = (REPO / 'docs' / 'layout.md').read_text()
    pkg = REPO / 'slip_estimator'
    missing = [f'slip_estimator/{d.name}/' for d in pkg.iterdir()
               if (d / '__init__.py').exists() and f'slip_estimator/{d.name}/' not in layout]
    listed_by_file = [pkg, pkg / 'core', pkg / 'ros', pkg / 'sim']
    missing += [p.relative_to(REPO).as_posix() for d in listed_by_file for p in d.glob('*.py')
                if not p.name.startswith('__') and not re.search(rf'\b{p.name}\b', layout)]
    assert not missing, f'docs/layout.md does not list {missing}'


def test_readme_figures_are_the_docs_figures():
    """The README quotes measured figures; each must stand in the page that measures them, so
    a figure updated there and not here (or typed here alone) fails."""
    section = README.read_text().split('## What it achieves', 1)[1].split('\n## ', 1)[0]
    docs = ' '.join(p.read_text() for p in PAGES[1:])
    figures = set(re.findall(r'\d+\.\d+|\d+-\d+', section))
    assert figures
    assert not {f for f in figures if f not in docs}, {f for f in figures if f not in docs}
