"""`spq report --quick` end to end: every section present, images embedded, figures sane."""

from __future__ import annotations

import re

import pandas as pd
import pytest

from harness.cli import main


@pytest.fixture(scope="module")
def report_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    # two processes on any machine: test_the_suites_side_by_side_write_what_one_process_writes compares
    # this run's pooled tables with a serial run
    assert main(["report", "--quick", "--workers", "2", "--out", str(out)]) == 0
    return out


def test_the_report_has_every_section_and_embeds_every_chart(report_dir):
    page = (report_dir / "index.html").read_text()
    from harness.report.assemble import SUITES

    titles = re.findall(r"<h2 id='s\d+'>(.*?)</h2>", page)
    assert len(titles) == len(SUITES)
    charts = sorted(report_dir.glob("*.png"))
    assert len(charts) >= 3
    assert page.count("data:image/png;base64,") == len(re.findall(r"<figure>", page)) >= 3
    assert (report_dir / "REPORT.md").read_text().startswith("# spq report")


def test_the_page_leads_with_the_verdict_and_the_four_pictures(report_dir):
    page = (report_dir / "index.html").read_text()
    verdict, first_section = page.index("id='verdict'"), page.index("<h2 id='s0'>")
    assert verdict < first_section
    assert "Pictures" in page[first_section:first_section + 200]
    for name in ("pictures_link_covers", "pictures_r_tradeoff", "pictures_robot", "pictures_penetration"):
        assert f'alt="{name}"' in page, name
    lead = page[verdict:first_section]
    for engine in ("spq", "coal"):
        assert f"<td>{engine}</td>" in lead
    assert "PCH–PCH" in lead  # Table I
    assert "the fastest peer per call" in lead
    links = set(re.findall(r"href='#(s\d+)'", lead))
    assert links and all(f"<h2 id='{a}'>" in page for a in links)
    # every chart has its one-line 'look at' caption; every table sits in a box that scrolls sideways
    assert page.count("<figure>") == page.count("<b class='look'>Look ")
    assert page.count("<table") == page.count("<div class='scroll'><table")


def test_the_reported_figures_are_sane(report_dir):
    engines = pd.read_csv(report_dir / "crosscheck_engines.csv")
    spq_row = engines[engines.engine == "spq"].iloc[0]
    assert spq_row.max_abs_error <= 1e-9 and spq_row.false_overlaps == 0 and spq_row.missed_overlaps == 0
    bench = pd.read_csv(report_dir / "bench_pch.csv")
    assert (bench.queries_per_s > 0).all()
    table1 = pd.read_csv(report_dir / "table1.csv")
    assert len(table1) == 6 and (table1.failed == 0).all()
    summary = pd.read_csv(report_dir / "continuity_summary.csv")
    assert len(summary) > 0
    depth = pd.read_csv(report_dir / "depth_oracle_summary.csv")
    assert len(depth) == 16 and (depth.max_abs_error_m <= 1e-8).all() and (depth.contained_pct == 100).all()


CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def test_the_page_renders_in_headless_chromium_with_every_image(report_dir, tmp_path):
    import shutil
    import subprocess

    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        pytest.skip("chromium not installed (.ci/run installs Debian's chromium)")
    url = (report_dir / "index.html").resolve().as_uri()
    base = [browser, *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=10000"]
    dom = subprocess.run([*base, "--dump-dom", url], capture_output=True, text=True, timeout=120).stdout
    assert 'data-images-ok="true"' in dom
    shot = tmp_path / "report.png"
    subprocess.run([*base, "--window-size=1200,2400", f"--screenshot={shot}", url], capture_output=True, timeout=120)
    assert shot.stat().st_size > 50_000
    # the first screen (1280 x 900 window) holds the whole verdict and the top of the first picture
    dom = subprocess.run([*base, "--window-size=1280,900", "--dump-dom", url], capture_output=True, text=True,
                         timeout=120).stdout
    screen = int(re.search(r'data-screen-height="(\d+)"', dom).group(1))
    assert int(re.search(r'data-verdict-bottom="(\d+)"', dom).group(1)) <= screen
    assert int(re.search(r'data-first-figure-top="(\d+)"', dom).group(1)) < screen - 100


def test_the_robot_section_agrees_with_coal_and_shows_no_auto_gradient_jump(report_dir):
    scene = pd.read_csv(report_dir / "robot_scene.csv")
    assert set(scene.policy) == {"auto", "pch", "stp-both"} and (scene.failed == 0).all()
    assert (scene.ms_per_config > 0).all()
    engines = pd.read_csv(report_dir / "robot_engines.csv").set_index("engine")
    assert engines.loc["coal", "max_abs_diff_vs_spq_m"] <= 1e-7
    continuity = pd.read_csv(report_dir / "robot_continuity.csv")
    auto = continuity[continuity.policy == "auto"]
    assert (auto.gradient_jumps_same_pair == 0).all() and (auto.largest_residual_after_bisection < 0.5).all()


def test_the_suites_side_by_side_write_what_one_process_writes(report_dir, tmp_path):
    """The suites that time nothing run on a pool of processes (spq report --workers; the module's
    report ran on two): same tables as a serial run, the time columns aside."""
    from harness.report.assemble import run_report

    only = ["continuity", "depth", "stability"]
    serial = tmp_path / "serial"
    run_report(serial, size="quick", only=only, workers=1)
    tables = sorted(serial.glob("*.csv"))
    assert len(tables) >= 3
    for path in tables:
        a, b = pd.read_csv(path), pd.read_csv(report_dir / path.name)
        timing = [c for c in a.columns if c == "seconds" or c.endswith(("_s", "_ms", "_us"))]
        pd.testing.assert_frame_equal(a.drop(columns=timing), b.drop(columns=timing))


def test_the_report_refuses_no_workers(tmp_path):
    from harness.report.assemble import run_report

    with pytest.raises(ValueError, match="workers"):
        run_report(tmp_path, size="quick", only=["continuity"], workers=0)


def test_every_suite_builds_its_config_at_every_size_and_standard_is_never_larger_than_full(tmp_path):
    """spq report's sizes: each suite's Config accepts its fields at every size, and no sample count of
    the standard run exceeds the full run's (nor a quick one's the standard's, where the suite's own quick
    mode does not set its sizes)."""
    import dataclasses

    from harness.report.assemble import SIZES, SUITES

    counts = ("per_bucket", "stp_per_bucket", "agreement_poses", "poses", "directions", "configs", "steps",
              "engine_configs", "repeats", "tasks", "queries", "generated_cases", "workers")
    for suite in SUITES:
        configs = {size: suite.config(size, 0, tmp_path) for size in SIZES}
        fields = {f.name for f in dataclasses.fields(configs["full"])}
        for name in fields & set(counts):
            q, s, f = (getattr(configs[size], name) for size in SIZES)
            if None in (q, s, f):
                continue
            assert s <= f, (suite.name, name, s, f)
            own_quick = getattr(configs["quick"], "quick", False)
            assert q <= s or own_quick or name == "workers", (suite.name, name, q, s)


def test_the_report_refuses_an_unknown_size_and_compile_part(tmp_path):
    from harness.report.assemble import run_report
    from harness.report.compile import compile_part

    with pytest.raises(ValueError, match="size"):
        run_report(tmp_path, size="huge", only=["continuity"])
    with pytest.raises(ValueError, match="compile part"):
        compile_part("everything")


def test_the_run_metadata_names_the_processor_and_its_caches(tmp_path):
    """Ratios move with the host, so every report names its CPU: the model from /proc/cpuinfo (platform
    leaves it empty on Linux), the CPU LLVM compiles for, and the data and unified caches from sysfs."""
    from llvmlite import binding

    from harness.report.meta import describe_cpu, run_metadata

    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor\t: 0\nvendor_id\t: Acme\nmodel name\t: Acme Turbo 9000\n\n"
                       "processor\t: 1\nmodel name\t: Acme Turbo 9000\n")
    for i, (level, kind, size) in enumerate([(1, "Data", "48K"), (1, "Instruction", "32K"), (3, "Unified", "16384K"),
                                             (2, "Unified", "2048K")]):
        folder = tmp_path / "cpu0" / "cache" / f"index{i}"
        folder.mkdir(parents=True)
        for name, value in (("level", level), ("type", kind), ("size", size)):
            (folder / name).write_text(f"{value}\n")
    llvm = binding.get_host_cpu_name()
    assert describe_cpu(cpuinfo, tmp_path / "cpu0") == f"Acme Turbo 9000 (LLVM: {llvm}; L1d 48K, L2 2048K, L3 16384K)"
    bare = describe_cpu(tmp_path / "no-such-file", tmp_path / "no-such-cpu")
    assert bare.endswith(f"(LLVM: {llvm})")
    machine = run_metadata()["machine"]
    assert f"LLVM: {llvm}" in machine and machine.endswith(" cpus")


def test_the_verdict_names_the_fastest_peer_per_call():
    from harness.report.verdict import fastest_peer_per_call

    rows = [("spq", "per-call", "all", 480.0), ("coal", "per-call", "all", 240.0), ("mujoco", "per-call", "all", 320.0),
            ("spq", "batched", "all", 1100.0), ("fcl", "per-call", "overlapping", 900.0)]
    bench = pd.DataFrame([{"pair": "PCH-PCH", "engine": e, "mode": m, "poses": p, "queries_per_s": q}
                          for e, m, p, q in rows])
    name, ratio = fastest_peer_per_call(bench)
    assert name == "mujoco" and ratio == pytest.approx(1.5)  # batched and overlapping-only rows do not count
    assert fastest_peer_per_call(bench[bench.engine == "spq"]) is None
    assert fastest_peer_per_call(None) is None
