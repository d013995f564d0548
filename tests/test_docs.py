"""The user documentation stays true: its results tables are the committed runs', its links
resolve, and the README stays short and free of lab-notebook details.

- Drift: every ``<!-- BEGIN GENERATED: name -->`` block in README.md and ``docs/`` equals what
  ``python -m experiments.docs_tables`` renders from ``experiments/results/`` now.
- Links: every relative link and image in README.md and ``docs/`` names a file of the checkout,
  and every ``#anchor`` a heading of its target (GitHub's heading slugs).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from experiments import docs_tables

ROOT = Path(__file__).resolve().parent.parent
DOCS = docs_tables.doc_files(ROOT)


def _metrics(mae: float, baselines: tuple[float, float, float], corr: float = 0.6,
             dataset: str = "webcam_clipart") -> dict:
    """A Sec. IV-A metrics.json with the fields the tables read."""
    names = docs_tables.BASELINES
    return {
        "test_mae": mae,
        "curve_corr": corr,
        "baselines": {n: {"test_mae": b} for n, b in zip(names, baselines)},
        "counts": {"test": 1000},
        "dataset": {"name": dataset, "config": "synthetic"},
        "provenance": {"command": "python -m experiments.webcam_clipart",
                       "code": "git " + "a" * 40 + " + uncommitted changes"},
        "run": {"finished_utc": "2030-01-01 00:00 UTC", "machine": "a CPU, 2 cores"},
    }


# ----------------------------------------------------------------------------- drift

def test_every_generated_block_matches_the_committed_results():
    stale = docs_tables.check(ROOT)
    assert not stale, ("generated tables differ from experiments/results/ (run `python -m "
                       "experiments.docs_tables`): " + ", ".join(stale))


def test_the_docs_quote_the_generated_tables():
    """The README's headline and the results pages are generated blocks, not typed copies."""
    names = {m.group(1) for p in DOCS for m in docs_tables._BLOCK.finditer(p.read_text())}
    assert {"sec4a_headline", "sec4a_webcam_clipart", "sec4a_cmu_seasons", "benchmark",
            "map_summarization", "map_summarization_conditions"} <= names, names
    assert "sec4a_headline" in {m.group(1) for m in
                                docs_tables._BLOCK.finditer((ROOT / "README.md").read_text())}


def test_check_finds_an_edited_figure_and_update_restores_it(tmp_path):
    (tmp_path / "docs").mkdir()
    run = tmp_path / "experiments" / "results" / "sec4a" / "webcam_clipart_seed0"
    run.mkdir(parents=True)
    (run / "metrics.json").write_text(json.dumps(_metrics(0.10, (0.15, 0.14, 0.13))))
    body = docs_tables.render_blocks(tmp_path)["sec4a_webcam_clipart"]
    doc = tmp_path / "docs" / "r.md"
    block = f"<!-- BEGIN GENERATED: sec4a_webcam_clipart -->\n{body}" \
            "<!-- END GENERATED: sec4a_webcam_clipart -->\n"
    (tmp_path / "README.md").write_text("# x\n")
    doc.write_text("# r\n\n" + block)
    assert docs_tables.check(tmp_path) == []
    doc.write_text("# r\n\n" + block.replace("0.1000", "0.0990"))  # a figure typed by hand
    assert docs_tables.check(tmp_path) == ["docs/r.md: sec4a_webcam_clipart"]
    assert docs_tables.update(tmp_path) == [doc]
    assert docs_tables.check(tmp_path) == [] and "0.1000" in doc.read_text()
    doc.write_text("<!-- BEGIN GENERATED: nope -->\nx\n<!-- END GENERATED: nope -->\n")
    with pytest.raises(ValueError, match="docs/r.md: generated block 'nope'"):
        docs_tables.update(tmp_path)


# ----------------------------------------------------------------------------- tables

def test_seed_table_has_each_seed_and_the_spread():
    runs = [(0, _metrics(0.10, (0.15, 0.14, 0.13))), (1, _metrics(0.16, (0.18, 0.17, 0.16))),
            (2, _metrics(0.12, (0.15, 0.15, 0.15)))]
    table = docs_tables.sec4a_seed_table(runs)
    rows = [line for line in table.splitlines() if line.startswith("| ")]
    assert len(rows) == 1 + 3 + 1  # header, a row per seed, mean ± sd
    assert rows[1].startswith("| 0 (default, `make demo`) | **0.1000** |")
    # RP against the best baseline of its own seed: (0.10 - 0.13) / 0.13, 0 %, -20 %.
    assert "-23.1 %" in rows[1] and "+0.0 %" in rows[2] and "-20.0 %" in rows[3]
    # mean 0.1267, sample sd 0.0306 of the three RP figures.
    assert "0.1267 ± 0.0306" in rows[4] and "range -23.1 to +0.0 %" in rows[4]
    assert "`python -m experiments.webcam_clipart`; 2030-01-01 00:00 UTC; a CPU, 2 cores; " \
           "git aaaaaaaaaaaa + uncommitted changes" in table


def test_headline_says_the_spread_and_the_default_seed():
    runs = [(0, _metrics(0.10, (0.15, 0.14, 0.13))), (1, _metrics(0.16, (0.18, 0.17, 0.16)))]
    table = docs_tables.sec4a_headline({"webcam_clipart": runs, "cmu_seasons": []})
    assert "| Webcam Clip Art | 0, 1 | 0.1300 ± 0.0424 |" in table
    assert "from -23.1 to +0.0 %" in table and "0.1000 vs 0.1300 (-23.1 %)" in table
    assert "| Extended CMU Seasons | none committed yet |" in table


def test_mean_sd():
    assert docs_tables.mean_sd([1.0, 2.0, 3.0]) == (2.0, 1.0)
    mean, sd = docs_tables.mean_sd([5.0])
    assert mean == 5.0 and sd != sd  # one value has no spread


def test_collect_stamps_the_run(tmp_path):
    work = tmp_path / "run"
    work.mkdir()
    m = _metrics(0.1, (0.2, 0.2, 0.2))
    del m["run"]
    (work / "metrics.json").write_text(json.dumps(m))
    out = docs_tables.collect(work, "webcam_clipart_seed3", root=tmp_path)
    assert out == tmp_path / "experiments/results/sec4a/webcam_clipart_seed3/metrics.json"
    stamped = json.loads(out.read_text())
    assert stamped["test_mae"] == 0.1 and stamped["run"]["finished_utc"].endswith("UTC")
    assert "cores" in stamped["run"]["machine"]
    with pytest.raises(ValueError, match="a run of webcam_clipart, not of cmu_seasons_seed1"):
        docs_tables.collect(work, "cmu_seasons_seed1", root=tmp_path)
    with pytest.raises(ValueError, match=re.escape(
            "expected <webcam_clipart|cmu_seasons|robotcar_day>_seed<N>")):
        docs_tables.collect(work, "seed1", root=tmp_path)


# ----------------------------------------------------------------------------- links

def slug(heading: str) -> str:
    """GitHub's anchor for a Markdown heading: lower case, punctuation dropped, spaces to -."""
    text = re.sub(r"`|\*\*|\[|\]\([^)]*\)", "", heading.strip()).lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """Every heading anchor of a Markdown file (repeats get -1, -2 as on GitHub)."""
    seen: dict[str, int] = {}
    out = set()
    in_code = False
    for line in path.read_text().splitlines():
        if line.startswith("```"):
            in_code = not in_code
        m = None if in_code else re.match(r"#{1,6} (.+)", line)
        if m:
            s = slug(m.group(1))
            n = seen.get(s, 0)
            seen[s] = n + 1
            out.add(s if n == 0 else f"{s}-{n}")
    out |= set(re.findall(r'<a (?:name|id)="([^"]+)"', path.read_text()))
    return out


def links(path: Path) -> list[str]:
    """The targets of Markdown links and images, and of HTML src/href, outside code."""
    text = re.sub(r"^```.*?^```", "", path.read_text(), flags=re.DOTALL | re.MULTILINE)
    text = re.sub(r"`[^`\n]*`", "", text)
    found = re.findall(r"\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)", text)
    found += re.findall(r'(?:src|href)="([^"]+)"', text)
    return found


def test_slug_follows_github():
    assert slug("Reproducing the paper") == "reproducing-the-paper"
    assert slug("Sec. IV-A: `make demo`, over seeds") == "sec-iv-a-make-demo-over-seeds"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_and_anchor_resolves(doc):
    broken = []
    for target in links(doc):
        if re.match(r"[a-z]+:", target):  # https:, mailto: (not fetched: no network in tests)
            continue
        file, _, anchor = target.partition("#")
        dest = (doc.parent / file).resolve() if file else doc
        if not dest.exists():
            broken.append(f"{target}: no such file")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            broken.append(f"{target}: no heading #{anchor} in {dest.relative_to(ROOT)}")
    assert not broken, f"{doc.relative_to(ROOT)}: " + "; ".join(broken)


# ----------------------------------------------------------------------------- the README

def prose(text: str) -> str:
    """The text a user reads as prose: outside generated blocks (their captions name runs,
    with dates and commits), code blocks and inline code (an example's times are input)."""
    text = re.sub(r"<!-- BEGIN GENERATED: (\S+) -->.*?<!-- END GENERATED: \1 -->", "", text,
                  flags=re.DOTALL)
    text = re.sub(r"^```.*?^```", "", text, flags=re.DOTALL | re.MULTILINE)
    text = re.sub(r"\]\([^)]*\)", "]", text)  # link targets (URLs may hold hex)
    return re.sub(r"`[^`\n]*`", "", text)


def test_readme_is_short_and_complete():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 350
    for must in ("make demo", "make test", "pip install -e .", "make install",
                 "source .venv/bin/activate", "@inproceedings", "## License"):
        assert must in text, must


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_docs_speak_of_the_tool_as_it_is(doc):
    """No dates, load averages, commit hashes or issue numbers in the prose: those belong to
    the generated captions, the result files and the changelog."""
    text = prose(doc.read_text())
    found = [m.group(0) for pattern in (
        r"\b20\d\d-\d\d-\d\d\b",                                        # a date
        r"\bissue #?\d+|#\d+\b",                                          # an issue
        r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*\d)[0-9a-f]{7,40}\b",             # a commit
        r"\bload(?: average)? \d",                                          # a load
    ) for m in re.finditer(pattern, text)]
    assert not found, f"{doc.relative_to(ROOT)}: {found}"


@pytest.mark.slow
def test_quick_start_runs_as_written(tmp_path):
    """The README's quick start, as a user pastes it after the install: each ``$`` line runs
    in a shell in an empty folder (``python`` is this interpreter) and prints the lines the
    README shows, numbers aside; then its Python block runs."""
    import os
    import subprocess
    import sys

    from tests.test_readme_own_data import _masked, console_steps, section_blocks

    blocks = section_blocks((ROOT / "README.md").read_text(), "## Quick start")
    steps = [s for lang, body in blocks if lang == "console" for s in console_steps(body)]
    assert any("rp_jax.keypoints" in c and "-synthetic" in c for c, _ in steps), steps
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    for command, expected in steps:
        proc = subprocess.run(["bash", "-c", command], cwd=tmp_path, env=env, text=True,
                              capture_output=True, timeout=300, check=False)
        output = proc.stdout + proc.stderr
        assert proc.returncode == 0, f"$ {command}\n{output}"
        printed = [_masked(line) for line in output.splitlines()]
        missing = [line for line in expected if line.strip() and _masked(line) not in printed]
        assert not missing, f"$ {command}\nnot printed: {missing}\n--- it printed:\n{output}"
    assert (tmp_path / "keypoints" / "rocket_repeatability.png").exists()
    for lang, body in blocks:
        if lang == "python":
            scope: dict = {}
            exec(compile(body, "README.md (Quick start)", "exec"), scope)  # noqa: S102
            assert scope["scores"].shape == (4, len(scope["rp"].schedule.labels))


def test_map_summarization_headline_reads_the_coarsest_threshold():
    acc = {m: {r: {"0.5m_5deg": a - 5, "5m_10deg": a} for r, a in zip(("0.5", "0.9"), accs)}
           for m, accs in (("rp", (90.0, 50.0)), ("kcover", (89.0, 47.5)))}
    metrics = {"ratios": ["0.5", "0.9"], "methods": ["rp", "kcover"], "accuracy": acc,
               "provenance": {"command": "python -m experiments.map_summarization",
                              "code": "git " + "b" * 40, "date": "2030-01-01 00:00 UTC",
                              "machine": "a CPU, 2 cores"}}
    table = docs_tables.map_summarization_headline(metrics)
    assert "| method | 50 % pruned | 90 % pruned |" in table
    assert "| rp | 90.0 | 50.0 |" in table and "| kcover | 89.0 | 47.5 |" in table
    assert "Within (5 m, 10°);" in table and "(docs/results/map_summarization.md)" in table
    # User documentation: no run's date, machine or commit.
    assert "2030" not in table and "bbbbbb" not in table and "a CPU" not in table
    with pytest.raises(ValueError, match="not the layout"):
        docs_tables.map_summarization_headline({"ratios": []})


def test_recipe_selection_ranks_the_candidates_by_their_mean_over_ratios_and_thresholds():
    def acc(a05, a5):
        return {r: {"0.5m_5deg": a05, "5m_10deg": a5} for r in ("0.5", "0.9")}

    metrics = {"ratios": ["0.5", "0.9"], "queries": 40, "slice": 6, "seeds": [0, 1],
               "methods": ["rp_paper", "rp", "outcome", "rp_cmu_kcover", "kcover"],
               "accuracy": {"rp_paper": acc(50.0, 60.0), "rp": acc(99.0, 99.0),
                            "outcome": acc(70.0, 80.0), "rp_cmu_kcover": acc(60.0, 80.0),
                            "kcover": acc(98.0, 98.0)},
               "labels": {"outcome": "outcome scorer"},
               "provenance": {"command": "python -m experiments.map_summarization",
                              "code": "git " + "c" * 40, "date": "2030-01-01 00:00 UTC",
                              "machine": "a CPU, 2 cores"}}
    table = docs_tables.recipe_selection_table(metrics).splitlines()
    rows = [line for line in table if line.startswith("| `")]
    # rp (an alias of the current recipe) and the baselines are not candidates
    assert rows == ["| `outcome` | outcome scorer | 75.00 |",
                    "| `rp_cmu_kcover` | rp_cmu_kcover | 70.00 |",
                    "| `rp_paper` | rp_paper | 55.00 |"]
    assert "slice 6, seeds [0, 1]" in "\n".join(table)
    assert "No recipe-selection run" in docs_tables.recipe_selection_table(None)
    with pytest.raises(ValueError, match="not the layout"):
        docs_tables.recipe_selection_table({"methods": ["outcome"], "accuracy": {}})


def test_scorer_validation_ranks_the_settings_by_the_mean_of_both_scorers():
    def result(seeds, hidden, outcome, agnostic, pairs):
        return {"slice": 6, "seeds": [0, 1, 2],
                "validation": {"pairs": 5000, "queries_correct": 60},
                "settings": {"seeds": seeds, "hidden": hidden, "depth": 2, "epochs": 6,
                             **({"members": 3} if hidden == 128 else {})},
                "feature_auc": {f"f{i}": 0.5 for i in range(30 + hidden // 64)},
                "variants": {"all": {"auc": {"outcome": outcome, "outcome_agnostic": agnostic},
                                     "training": {"pairs_of_correct_queries": pairs}}},
                "provenance": {"command": "python -m experiments.map_summarization."
                               "outcome_scorer", "code": "git " + "d" * 40,
                               "date": "2030-01-01 00:00 UTC", "machine": "a CPU, 2 cores"}}

    # b: the twin better, the time-aware worse than a; the mean decides (0.815 > 0.805).
    table = docs_tables.scorer_validation_table(
        [("a", result([0], 64, 0.81, 0.80, 1200)),
         ("b", result([5, 6, 7], 128, 0.80, 0.83, 3400))]).splitlines()
    rows = [line for line in table if line.startswith("| `")]
    assert rows == ["| `b` | 5, 6, 7 | 3,400 | 32 | 128 x 2, 6 | 3 | 0.800 | 0.830 | 0.815 |",
                    "| `a` | 0 | 1,200 | 31 | 64 x 2, 6 | 1 | 0.810 | 0.800 | 0.805 |"]
    assert "slice 6 of world seeds [0, 1, 2] (5,000 pairs of 60 correctly" in "\n".join(table)
    assert "Made with other code" not in "\n".join(table)  # both rows from one commit
    # A row made with other code (an earlier RP or other features) is named as such.
    old = result([0], 64, 0.70, 0.70, 1200)
    old["provenance"] = {**old["provenance"], "code": "git " + "e" * 40}
    table = docs_tables.scorer_validation_table(
        [("a", result([0], 64, 0.81, 0.80, 1200)), ("old", old),
         ("b", result([5, 6, 7], 128, 0.80, 0.83, 3400))])
    assert table.rstrip().endswith("each file's `provenance` says which): `old`.")
    assert "No scorer validation" in docs_tables.scorer_validation_table([])
    with pytest.raises(ValueError, match="not the layout"):
        docs_tables.scorer_validation_table([("a", {"variants": {}})])


def test_by_source_table_averages_each_group_without_the_own_hour():
    T = 24
    gt = [[0.0] * T for _ in range(T)]
    for s in range(T):
        for t in range(T):
            if s in docs_tables.DAY_HOURS and t in docs_tables.DAY_HOURS:
                gt[s][t] = 0.1
            if s in docs_tables.DARK_HOURS and t in docs_tables.DARK_HOURS:
                gt[s][t] = 0.2
        gt[s][s] = 0.9  # the own hour: never averaged in
    gt[1][2] = None  # a gap is skipped, not a zero
    pred = [[v if v is None else v / 2 for v in row] for row in gt]
    metrics = {"by_source_slot": {"gt": gt, "pred": pred},
               "schedule": {"labels": [f"{h:02d}:00" for h in range(T)]},
               "provenance": {"command": "python -m experiments.robotcar_day"}}
    text = docs_tables.sec4a_by_source_table([(0, metrics)])
    assert "| 0 | by day | 0.100 | 0.050 | 0.000 | 0.000 |" in text
    assert "| 0 | at night | 0.000 | 0.000 | 0.200 | 0.100 |" in text
    with pytest.raises(ValueError, match="not a whole-day run"):
        docs_tables.sec4a_by_source_table([(0, {**metrics, "by_source_slot": None})])


def test_night_factors_table_has_a_row_per_factor_and_the_run():
    per = {"frames": 2, "keypoints_median": 300.0, "redetected_mean": 12.5,
           "redetected_median": 9.0, "redetected_max": 40, "enough_redetected": 0.5,
           "localized": {"0.25m_2deg": 0.0, "0.5m_5deg": 0.5, "5m_10deg": 0.5},
           "gain_median": 3214.0, "exposure_ms_median": 90.1}
    out = {"world": {"seed": 3, "size": "full"}, "min_inliers": 12,
           "results": {"night-rain": {"as_taken": per, "by_day": dict(per, gain_median=6.0)}},
           "provenance": {"command": "python -m x", "date": "2030-01-01 10:00 UTC",
                          "machine": "AMD EPYC", "code": "git 0123456789abcdef"}}
    text = docs_tables.night_factors_tables(out)
    assert "**night-rain** (2 frames of world seed 3, size full)" in text
    assert ("| as taken (the preset's frame) | 300 | 12.5 / 9 / 40 | 50 % | 50 % | 50 % | 3214 "
            "| 90.1 ms |") in text
    assert "| the same view by day (the reference traversal's time and sky) |" in text
    assert "frames re-detecting >= 12" in text and "`python -m x`; 2030-01-01 10:00 UTC" in text
    assert "No night-factor result" in docs_tables.night_factors_tables(None)


def test_the_counterfactual_nights_block_shows_the_night_group_only():
    metrics = docs_tables.read_json(ROOT / docs_tables.MAPSUM_CONDITIONS)
    text = docs_tables.nights_counterfactual_tables(metrics)
    assert "### Primary comparison: does knowing the condition help at night?" in text
    assert "### Night (night, night-rain)" in text and "### Full map by condition" in text
    assert "### Twilight" not in text and "### Day (" not in text
    assert "night, 90 %, (5 m, 10 deg)" in text and "twilight, 90 %" not in text
    assert text.rstrip().endswith(".") and "Run: `python -m experiments.map_summarization" in text
    assert "No counterfactual by-condition result" in docs_tables.nights_counterfactual_tables(None)
