"""The docs: the README's Sphinx build (warnings as errors; the gallery's examples run at build time), and the
rendered pages in headless Chromium (Debian's ``chromium`` and ``chromium-driver``, driven by Selenium): a
screenshot of the index, an API page and a gallery page, with no broken image, no broken link and no raw LaTeX
in the index's table of contents."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from urllib.parse import unquote, urlparse

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
CHROMIUM, CHROMEDRIVER = Path("/usr/bin/chromium"), Path("/usr/bin/chromedriver")

#: The pages opened in the browser: the index, an API page, and the gallery's compositing example.
PAGES = ("index.html", "api/geometry.html", "auto_examples/plot_composite_virtual_object.html")

#: Every image, and every link to another page of the docs, that the pages hold.
BROKEN_IMAGES = "return Array.from(document.images).filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.src)"
LINKS = "return Array.from(document.querySelectorAll('a[href]')).map(a => a.href)"


@pytest.fixture(scope="module")
def html(tmp_path_factory) -> Path:
    """The README's docs build (``sphinx -W --keep-going``), into a temporary folder."""
    out = tmp_path_factory.mktemp("docs")
    run = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", "-d",
                          str(out / "doctrees"), str(ROOT / "docs"), str(out / "html")],
                         capture_output=True, text=True, timeout=1800, check=False)
    assert run.returncode == 0, run.stderr[-6000:]
    return out / "html"


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    from selenium import webdriver  # lazy: only this test drives a browser
    from selenium.webdriver.chrome.service import Service

    assert CHROMIUM.is_file() and CHROMEDRIVER.is_file(), (
        "the browser test needs Debian's chromium and chromium-driver (the README's test command installs them)")
    profile = tmp_path_factory.mktemp("chromium")
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1280,1600",
                 f"--user-data-dir={profile}", f"--crash-dumps-dir={profile}", "--disable-dev-shm-usage"):
        options.add_argument(flag)
    home = {"HOME": str(profile), "XDG_CONFIG_HOME": str(profile), "XDG_CACHE_HOME": str(profile)}
    service = Service(str(CHROMEDRIVER), env={**os.environ, **home})  # nothing written into the user's home
    driver = webdriver.Chrome(service=service, options=options)
    yield driver
    driver.quit()


def _local_target(url: str) -> tuple[Path, str] | None:
    """A ``file://`` link's file and fragment; ``None`` for any other scheme (not fetched: no network)."""
    parsed = urlparse(url)
    return (Path(unquote(parsed.path)), parsed.fragment) if parsed.scheme == "file" else None


@pytest.mark.slow
def test_the_docs_render_in_chromium_without_broken_images_or_links(html, browser, tmp_path) -> None:
    from PIL import Image

    for page in PAGES:
        path = html / page
        assert path.is_file(), f"{page} was not built"
        browser.get(path.as_uri())
        assert browser.execute_script("return document.readyState") == "complete"
        assert browser.execute_script(BROKEN_IMAGES) == [], f"broken images on {page}"
        for url in browser.execute_script(LINKS):
            target = _local_target(url)
            if target is None:
                continue
            file, fragment = target
            assert file.exists(), f"{page} links to a missing {file}"
            if fragment and file.suffix == ".html":
                text = file.read_text(encoding="utf-8")
                assert f'id="{fragment}"' in text, f"{page} links to a missing anchor {file.name}#{fragment}"
        shot = tmp_path / (page.replace("/", "_") + ".png")
        assert browser.save_screenshot(str(shot))
        pixels = np.asarray(Image.open(shot).convert("L"), dtype=np.float32)
        assert pixels.shape[1] >= 1000 and pixels.std() > 10, f"{page} renders blank"
        if page == "index.html":
            toc = browser.execute_script(
                "return Array.from(document.querySelectorAll('.toctree-wrapper')).map(e => e.innerText).join()")
            assert "\\(" not in toc and "mathrm" not in toc, "raw LaTeX in the index's table of contents"
    gallery = browser.execute_script("return Array.from(document.images).filter(i => i.naturalWidth > 300).length")
    assert gallery >= 1, "the compositing example shows no figure"
