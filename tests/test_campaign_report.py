"""The static HTML report of a campaign store (lookout.studies.report).

The stores are written without simulating: each chunk gets synthetic metrics, a known
function of its sweep point and seed, so the plotted statistics can be checked exactly.
"""

import base64
import json
import re
import shutil
import subprocess

import numpy as np
import pytest

from lookout.studies import report as report_module
from lookout.studies.campaign import campaign_from_document
from lookout.studies.report import report_figures, write_report
from lookout.studies.store import CampaignStore

DOCUMENT = {
    "scenario": {"preset": "fossen-strand-1999", "simulation": {"duration": 20.0}},
    "seeds_per_point": 4,
    "chunk_runs": 2,
    "metrics": ["rms_error:position", "max_excursion:position"],
    "after": 10.0,
    "divergence": {"signal": "position", "limit": 50.0},
    "sweep": {
        "kind": "grid",
        "axes": [
            # the sea and the observer tuned to it
            {"field": ["plant.waves.peak_frequency", "observer.wave_frequency"], "values": [0.6, 0.8, 1.0], "name": "wave_frequency"},
            {"field": "sensor.dropout_probability", "values": [0.0, 0.1], "name": "dropout_probability"},
        ],
    },
}
FREQUENCIES, DROPOUTS, SEEDS = [0.6, 0.8, 1.0], [0.0, 0.1], 4
#: the one diverged run: point 4 (wave_frequency 1.0, dropout_probability 0.0), seed 3
DIVERGED_POINT, DIVERGED_SEED = 4, 3
METRICS, AXES = 2, 2
IMAGES = METRICS * AXES + METRICS + AXES  # metric figures, heat maps, diverged figures
PNG = b"\x89PNG\r\n\x1a\n"

pytestmark = pytest.mark.xdist_group("campaign_report")  # one worker builds the store


def rms(frequency, dropout, seed):
    return (0.2 + frequency**2) * (1.0 + 5.0 * dropout) * (1.0 + 0.1 * seed)


def excursion(frequency, dropout, seed):
    return 3.0 * rms(frequency, dropout, seed) + frequency


def expected(metric):
    """(points, seeds) of the synthetic metric, NaN at the diverged run."""
    values = np.asarray([[metric(f, d, s) for s in range(SEEDS)] for f in FREQUENCIES for d in DROPOUTS])
    values[DIVERGED_POINT, DIVERGED_SEED] = np.nan
    return values


def synthetic(campaign, chunk):
    point = campaign.points[chunk.point]
    frequency, dropout = point["wave_frequency"], point["dropout_probability"]
    diverged = np.asarray([chunk.point == DIVERGED_POINT and seed == DIVERGED_SEED for seed in chunk.seeds], dtype=float)
    result = {
        "rms_error__position": np.asarray([rms(frequency, dropout, seed) for seed in chunk.seeds]),
        "max_excursion__position": np.asarray([excursion(frequency, dropout, seed) for seed in chunk.seeds]),
    }
    for name in result:  # a diverged run's metrics are NaN, as metrics.reduce writes them
        result[name] = np.where(diverged == 1, np.nan, result[name])
    result["diverged"] = diverged
    result["seconds"] = np.asarray(0.1)
    return result


@pytest.fixture(scope="module")
def campaign():
    return campaign_from_document(json.loads(json.dumps(DOCUMENT)), "<test>")


@pytest.fixture(scope="module")
def store(campaign, tmp_path_factory):
    store = CampaignStore.open_or_create(tmp_path_factory.mktemp("complete") / "store.zarr", campaign)
    for chunk in campaign.chunks():
        store.write_chunk(campaign, chunk, synthetic(campaign, chunk))
    return store


@pytest.fixture(scope="module")
def report(store):
    figures = store.path.parent / "figures"
    path = write_report(store.path, figures_dir=figures)
    return path, figures


def test_report_is_one_self_contained_page(report, store):
    path, figures = report
    assert path == path.parent / "store-report.html" and path.exists()
    page = path.read_text()
    images = re.findall(r"<img\b[^>]*>", page)
    assert len(images) == IMAGES
    for tag in images:
        source = re.search(r'src="([^"]*)"', tag).group(1)
        assert source.startswith("data:image/png;base64,")
        assert base64.b64decode(source.split(",", 1)[1]).startswith(PNG)
    # nothing from the network: no remote src/href, no linked style sheet or script
    assert not re.search(r"""(src|href)\s*=\s*["']?\s*(https?:)?//""", page, re.IGNORECASE)
    assert "<link" not in page and not re.search(r"<script[^>]*\bsrc=", page)
    assert "complete: 12 of 12 chunks done (24 of 24 runs)" in page
    attrs = store.open().attrs  # provenance
    for key in ("title", "lookout_version", "created", "campaign_fingerprint"):
        assert str(attrs[key]) in page
    assert "fossen-strand-1999" in page.split('<section id="spec">', 1)[1]
    # the diverged run is in the table: point, wave_frequency, dropout_probability, seed
    table = page.split('id="diverged-runs"', 1)[1].split("</table>", 1)[0]
    rows = re.findall(r"<tr>(.*?)</tr>", table)
    assert [re.findall(r"<td>(.*?)</td>", row) for row in rows[1:]] == [["4", "1", "0", "3"]]
    assert "1 of 24 computed runs diverged" in page
    assert '<p id="image-check"' in page
    # the same figures as PNG files
    names = sorted(p.name for p in figures.glob("*.png"))
    assert len(names) == IMAGES and "heatmap-rms_error__position.png" in names
    assert "rms_error__position-vs-wave_frequency.png" in names and "diverged-vs-dropout_probability.png" in names
    assert all((figures / name).read_bytes().startswith(PNG) for name in names)


def test_partial_store_gets_a_partial_report(campaign, tmp_path):
    store = CampaignStore.open_or_create(tmp_path / "partial.zarr", campaign)
    for chunk in campaign.chunks()[:3]:
        store.write_chunk(campaign, chunk, synthetic(campaign, chunk))
    page = write_report(store.path, tmp_path / "out" / "partial.html").read_text()
    assert "partial: 3 of 12 chunks done (6 of 24 runs)" in page
    assert "not finished: 3 of 12 chunks done" in page
    assert len(re.findall(r"<img\b", page)) == IMAGES - AXES  # the 3 chunks hold no diverged run


def test_divergence_is_drawn_only_when_a_run_diverged(campaign, report, tmp_path):
    # the complete store has one diverged run: its figures and its table
    page = report[0].read_text()
    divergence = page.split('<section id="divergence">', 1)[1].split("</section>", 1)[0]
    assert len(re.findall(r"<img\b", divergence)) == AXES and 'id="diverged-runs"' in divergence
    # the first 3 chunks (points 0 and 1) hold none: one sentence, no figure, no table
    store = CampaignStore.open_or_create(tmp_path / "partial.zarr", campaign)
    for chunk in campaign.chunks()[:3]:
        store.write_chunk(campaign, chunk, synthetic(campaign, chunk))
    figures = tmp_path / "figures"
    page = write_report(store.path, tmp_path / "partial.html", figures_dir=figures).read_text()
    divergence = page.split('<section id="divergence">', 1)[1].split("</section>", 1)[0]
    assert '<p id="diverged-count">No run diverged (6 of 24 runs finished).</p>' in divergence
    assert "<img" not in divergence and "diverged-runs" not in divergence
    assert not any(name.startswith("diverged-") for name in report_figures(store.open(), store.campaign_document()))
    names = {p.name for p in figures.glob("*.png")}
    assert len(names) == IMAGES - AXES and not any(name.startswith("diverged-") for name in names)


def test_store_without_a_finished_chunk_says_so(campaign, tmp_path):
    store = CampaignStore.open_or_create(tmp_path / "empty.zarr", campaign)
    figures = tmp_path / "figures"
    page = write_report(store.path, figures_dir=figures).read_text()
    assert "not started: 0 of 12 chunks done (0 of 24 runs)" in page
    assert "No chunk has finished yet: 0 of 12 chunks (24 runs)." in page
    assert f"lookout campaign run SPEC --out {store.path}" in page
    # no empty plots, no tables of NaNs: the spec only
    assert "<img" not in page and "<figure" not in page
    for section in ("summary", "divergence", "heatmaps", "metric-rms_error__position"):
        assert f'id="{section}"' not in page and f'href="#{section}"' not in page
    assert 'id="spec-axes"' in page
    assert report_figures(store.open(), store.campaign_document()) == {}
    assert list(figures.glob("*")) == []
    # one chunk done: a partial report with figures
    chunk = campaign.chunks()[0]
    store.write_chunk(campaign, chunk, synthetic(campaign, chunk))
    page = write_report(store.path).read_text()
    assert "partial: 1 of 12 chunks done (2 of 24 runs)" in page and "No chunk has finished" not in page
    assert "<img" in page


def _rows(page: str, table_id: str) -> list[list[str]]:
    table = page.split(f'id="{table_id}"', 1)[1].split("</table>", 1)[0]
    return [re.findall(r"<t[dh]>(.*?)</t[dh]>", row) for row in re.findall(r"<tr>(.*?)</tr>", table, re.DOTALL)]


def test_spec_is_a_readable_table(report):
    page = report[0].read_text()
    spec = page.split('<section id="spec">', 1)[1].split("</section>", 1)[0]
    # what was run comes before what came out
    assert page.index('<section id="spec">') < page.index('<section id="summary">')
    scenario = dict(_rows(spec, "spec-scenario"))
    assert scenario == {
        "plant": "dp-vessel",
        "sensor": "position-heading",
        "observer": "passive (design fossen-strand-1999)",
        "reference": "none",
        "controller": "sinusoidal",
        "actuator": "ideal",
    }
    # the keys that differ from their kind's default, value and default: the duration among them
    changed = {row[0]: row[1:] for row in _rows(spec, "spec-changed")}
    assert changed["key"] == ["value", "default", "description"]
    assert changed["simulation.duration"] == ["20", "600", html_escape(description("simulation.duration"))]
    assert changed["sensor.noise_std"][:2] == ["[0.5, 0.5, 0.00174533]", "0"] and "sensor.dropout_probability" not in changed
    # every key in a collapsed table, nested keys dotted
    settings = {row[0]: row[1] for row in _rows(spec, "spec-settings")[1:]}
    assert settings["plant.bias.std"] == "[2000, 2000, 50000]" and settings["observer.notch_damping"] == "1"
    assert "plant.vessel" not in settings and spec.index("<details>") < spec.index('id="spec-settings"')
    campaign = dict((row[0], row[1]) for row in _rows(spec, "spec-campaign"))
    assert campaign["seeds"] == "4 per point: seeds 0 to 3, the same at every point"
    assert campaign["chunks"] == "2 runs per chunk: 12 chunks (6 points × 2 blocks of seeds)"
    assert campaign["metrics"].split("<br>") == [
        "rms_error:position: RMS estimation error of low-frequency position (m)",
        "max_excursion:position: largest excursion of low-frequency position (m)",
    ]
    assert campaign["metric window"] == "t ≥ 10 s (after = 10)"
    assert campaign["diverged"] == "the position error beyond 50 m at any record, or a truth or estimate that is not finite"
    assert campaign["trajectories kept"] == "none"
    assert "grid: 6 points, every combination of the axes" in spec
    assert _rows(spec, "spec-axes") == [
        ["axis", "field", "values", "applied"],
        ["wave_frequency", "plant.waves.peak_frequency, observer.wave_frequency", "0.6, 0.8, 1 (rad/s)", "sets the value"],
        ["dropout_probability", "sensor.dropout_probability", "0, 0.1", "sets the value"],
    ]
    # the raw JSON only collapsed, after the tables
    assert spec.count("<pre>") == 1 and spec.index('id="spec-axes"') < spec.rindex("<details>") < spec.index("<pre>")


def test_spec_defaults_window_and_divergence_rule():
    document = {key: value for key, value in json.loads(json.dumps(DOCUMENT)).items() if key not in ("after", "divergence")}
    document["scenario"] = campaign_from_document(json.loads(json.dumps(DOCUMENT)), "<test>").base.document()
    document["sweep"]["axes"][1] = {
        "name": "noise",
        "field": ["sensor.noise_std[0]", "sensor.noise_std[1]"],
        "range": [0.5, 2.0],
        "steps": 4,
        "scale": True,
    }
    spec = report_module._spec_html(document, [], 6, 2, 12)
    campaign = dict((row[0], row[1]) for row in _rows(spec, "spec-campaign"))
    assert campaign["metric window"] == "t ≥ 10 s: the second half of the run (the default)"
    assert campaign["diverged"] == "a truth or estimate that is not finite at any record (no divergence limit)"
    assert _rows(spec, "spec-axes")[2] == [
        "noise",
        "sensor.noise_std[0], sensor.noise_std[1]",
        "4 steps over [0.5, 2]: 0.5, 1, 1.5, 2",
        "× base value",
    ]


def html_escape(text: str) -> str:
    import html

    return html.escape(text)


def description(key: str) -> str:
    from lookout.scenario.file import composition_comments

    return composition_comments(campaign_from_document(json.loads(json.dumps(DOCUMENT)), "<test>").base.document())[key]


def test_figures_sit_in_two_columns_on_a_wide_page(report):
    page = report[0].read_text()
    style = page.split("<style>", 1)[1].split("</style>", 1)[0]
    assert re.search(r"\.figures\s*\{[^}]*display:\s*grid;[^}]*grid-template-columns:\s*repeat\(2,", style)
    assert re.search(r"@media\s*\(max-width:[^)]*\)\s*\{\s*\.figures\s*\{\s*grid-template-columns:\s*minmax\(0, 1fr\)", style)
    assert re.search(r"figure img\s*\{[^}]*width:\s*100%", style)
    # every figure of a section is in its grid
    for section in re.findall(r'<section id="(?:metric-[^"]*|heatmaps|divergence)">(.*?)</section>', page, re.DOTALL):
        assert section.count("<figure") == section.split('<div class="figures">', 1)[-1].count("<figure")


def test_plotted_numbers_are_the_statistics_of_the_runs(store):
    ds = store.open()
    figures = report_figures(ds, store.campaign_document())
    values = expected(rms)
    frequency = np.repeat(FREQUENCIES, len(DROPOUTS))
    ax = figures["rms_error__position-vs-wave_frequency.png"].axes[0]
    np.testing.assert_array_equal(ax.lines[0].get_xdata(), FREQUENCIES)
    medians = [np.nanmedian(values[frequency == f]) for f in FREQUENCIES]
    np.testing.assert_allclose(ax.lines[0].get_ydata(), medians, rtol=1e-12)
    assert "(m)" in ax.get_ylabel() and "rad/s" in ax.get_xlabel()
    # the band: the 10th and 90th percentiles of the same runs
    band = ax.collections[0].get_paths()[0].vertices[:, 1]
    at = values[frequency == 1.0]
    low, high = np.percentile(at[np.isfinite(at)], [10, 90])
    assert np.isclose(band, low).any() and np.isclose(band, high).any()
    # the heat map: median over seeds, wave_frequency across, dropout_probability up
    image = figures["heatmap-rms_error__position.png"].axes[0].images[0].get_array()
    np.testing.assert_allclose(np.ma.filled(image, np.nan), np.nanmedian(values, axis=1).reshape(3, 2).T, rtol=1e-12)
    # one run in 8 diverged at wave_frequency 1.0
    diverged = figures["diverged-vs-wave_frequency.png"].axes[0].lines[0].get_ydata()
    np.testing.assert_allclose(diverged, [0.0, 0.0, 1 / 8])


def test_latin_hypercube_and_three_axis_grid_figures():
    import xarray as xr

    rng = np.random.default_rng(0)
    points, seeds = 7, 3

    def dataset(kind, axes):
        coords = {"point": np.arange(points), "seed": np.arange(seeds)}
        for name, values in axes.items():
            coords[name] = ("point", np.asarray(values), {"long_name": name, "fields": name, "scale": 0, "units": "s"})
        data = rng.lognormal(size=(points, seeds)) * np.logspace(0, 4, points)[:, None]
        data[2] = np.nan  # a point not computed yet
        return xr.Dataset(
            {
                "final__x": (("point", "seed"), data, {"units": "m", "long_name": "final value of x", "metric": "final:x"}),
                "diverged": (("point", "seed"), np.where(np.isnan(data), np.nan, 0.0)),
            },
            coords=coords,
            attrs={"sweep_kind": kind, "axes": json.dumps(list(axes))},
        )

    latin = report_figures(dataset("latin-hypercube", {"a": rng.random(points), "b": rng.random(points)}), None)
    assert sorted(latin) == ["final__x-vs-a.png", "final__x-vs-b.png"]  # no run diverged: no divergence figures
    ax = latin["final__x-vs-a.png"].axes[0]
    assert ax.containers and ax.get_yscale() == "log" and ax.get_xlabel() == "a (s)"

    grid = {"a": [1, 1, 1, 2, 2, 2, 2], "b": [0, 1, 1, 0, 0, 1, 1], "c": [0, 0, 1, 0, 1, 0, 1]}
    figures = report_figures(dataset("grid", grid), None)
    assert "heatmap-final__x.png" in figures
    image = figures["heatmap-final__x.png"].axes[0].images[0].get_array()
    assert image.shape == (2, 2) and not np.ma.is_masked(image)

    # every finished run diverged: no metric figure (it would be empty), the divergence ones
    ds = dataset("grid", grid)
    ds["diverged"] = ds["diverged"].fillna(0.0) * 0.0 + 1.0
    ds["final__x"] = ds["final__x"] * np.nan
    assert sorted(report_figures(ds, None)) == ["diverged-vs-a.png", "diverged-vs-b.png", "diverged-vs-c.png"]


def _browser():
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        found = shutil.which(name)
        if found:
            try:  # e.g. Ubuntu's chromium-browser is a stub that asks for snap
                works = subprocess.run([found, "--version"], capture_output=True, timeout=30).returncode == 0
            except (OSError, subprocess.TimeoutExpired):
                works = False
            if works:
                return found
    pytest.skip("no headless browser (chromium) on this machine: install Debian's chromium to run this test")


def _chromium(browser, tmp_path, name, url, *arguments):
    flags = [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={tmp_path / f'profile-{name}'}",
    ]
    return subprocess.run([browser, *flags, *arguments, url], capture_output=True, text=True, timeout=60)


def test_report_renders_in_headless_browser(report, tmp_path):
    browser = _browser()
    url = report[0].resolve().as_uri()

    def run(name, *arguments):
        return _chromium(browser, tmp_path, name, url, *arguments)

    shot = tmp_path / "shot.png"
    done = run("screenshot", f"--screenshot={shot}", "--window-size=1200,1600")
    assert shot.exists(), done.stderr[-2000:]
    from matplotlib.image import imread

    pixels = imread(shot)[..., :3]
    assert pixels.shape[:2] == (1600, 1200)
    assert pixels.std() > 0.05
    codes = np.round(pixels * 255).astype(np.int64)
    codes = (codes[..., 0] << 16) | (codes[..., 1] << 8) | codes[..., 2]
    _, counts = np.unique(codes, return_counts=True)
    assert 1.0 - counts.max() / codes.size > 0.01  # more than 1 % is not the background

    dom = run("dom", "--dump-dom", "--virtual-time-budget=5000")
    assert f"images loaded: {IMAGES} of {IMAGES}" in dom.stdout, dom.stderr[-2000:]


_LAYOUT_PROBE = """<script>window.addEventListener("load", function () {
  var boxes = [];
  document.querySelectorAll("#metric-rms_error__position figure img").forEach(function (image) {
    var box = image.getBoundingClientRect();
    boxes.push([box.left, box.top, box.width]);
  });
  document.body.setAttribute("data-layout", JSON.stringify({page: document.body.clientWidth, boxes: boxes}));
});</script>
</body>"""


def test_figures_in_two_columns_in_headless_browser(report, tmp_path):
    """On a wide window the two figures of a metric sit side by side, each filling half
    the page; on a narrow one they stack, each the page's width."""
    import html

    browser = _browser()
    probe = tmp_path / "probe.html"
    probe.write_text(report[0].read_text().replace("</body>", _LAYOUT_PROBE, 1))

    def layout(width):
        dom = _chromium(
            browser, tmp_path, f"layout-{width}", probe.resolve().as_uri(), f"--window-size={width},2000", "--virtual-time-budget=5000", "--dump-dom"
        )
        found = re.search(r'data-layout="([^"]*)"', dom.stdout)
        assert found, dom.stderr[-2000:]
        return json.loads(html.unescape(found.group(1)))

    wide = layout(1600)
    (left, top, width), (left2, top2, width2) = wide["boxes"]
    assert top == top2 and left2 > left + width and width == width2
    assert width > 0.4 * wide["page"]  # scaled to the column, not left at a fixed size
    narrow = layout(900)
    (left, top, width), (left2, top2, width2) = narrow["boxes"]
    assert left == left2 and top2 > top + 0.5 * width and width > 0.8 * narrow["page"]
