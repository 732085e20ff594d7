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

from lookout.studies.campaign import campaign_from_document
from lookout.studies.report import report_figures, write_report
from lookout.studies.store import CampaignStore

DOCUMENT = {
    "scenario": {"template": "fossen-strand-1999", "case": "paper", "settings": {"duration": 20.0}},
    "seeds_per_point": 4,
    "chunk_runs": 2,
    "metrics": ["rms_error:position", "max_excursion:position"],
    "sweep": {
        "kind": "grid",
        "axes": [
            {"field": "wave_frequency", "values": [0.6, 0.8, 1.0]},
            {"field": "dropout_probability", "values": [0.0, 0.1]},
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
    assert "not finished" in page
    assert len(re.findall(r"<img\b", page)) == IMAGES


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
            {"final__x": (("point", "seed"), data, {"units": "m", "long_name": "final value of x", "metric": "final:x"}),
             "diverged": (("point", "seed"), np.where(np.isnan(data), np.nan, 0.0))},
            coords=coords, attrs={"sweep_kind": kind, "axes": json.dumps(list(axes))})

    latin = report_figures(dataset("latin-hypercube", {"a": rng.random(points), "b": rng.random(points)}), None)
    assert sorted(latin) == ["diverged-vs-a.png", "diverged-vs-b.png", "final__x-vs-a.png", "final__x-vs-b.png"]
    ax = latin["final__x-vs-a.png"].axes[0]
    assert ax.containers and ax.get_yscale() == "log" and ax.get_xlabel() == "a (s)"

    grid = {"a": [1, 1, 1, 2, 2, 2, 2], "b": [0, 1, 1, 0, 0, 1, 1], "c": [0, 0, 1, 0, 1, 0, 1]}
    figures = report_figures(dataset("grid", grid), None)
    assert "heatmap-final__x.png" in figures
    image = figures["heatmap-final__x.png"].axes[0].images[0].get_array()
    assert image.shape == (2, 2) and not np.ma.is_masked(image)


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


def test_report_renders_in_headless_browser(report, tmp_path):
    browser = _browser()
    url = report[0].resolve().as_uri()

    def run(name, *arguments):
        flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", f"--user-data-dir={tmp_path / f'profile-{name}'}"]
        return subprocess.run([browser, *flags, *arguments, url], capture_output=True, text=True, timeout=60)

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
