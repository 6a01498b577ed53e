"""Make the light-stage figures of ``docs/lightstage.rst`` again from today's light stage (needs the MakeHuman
assets and Mitsuba; about 10 minutes on 2 cores), each stamped with the code it shows
(:mod:`kornia_ilum_lab.provenance`; ``tests/test_figures.py`` fails when the light stage has changed since).

    python docs/_scripts/make_lightstage_figures.py --assets ../shared/data/makehuman \
        --hdri ../shared/data/hdri ../shared/data/hdri_more

Writes into ``docs/_static/``:

- ``subjects_contact_sheet.png``: MakeHuman subjects under a studio light (:func:`preview.contact_sheet`);
- ``subsurface_pair.png``: one subject-view relit from its one-pass reflectance field, without and with the
  subsurface step, under the same real map;
- ``lightstage_contact_sheet.jpg``: 64 training portraits exactly as :class:`PortraitDataset` yields them
  (camera effects included), sorted by skin tone, each above its ground-truth diffuse, matte-silver and
  mirror spheres, with the bundled astronaut photograph's face crop first for comparison. The portraits come
  from a cache rendered afresh (one view of each training subject of seeds 0-29, into a temporary folder), so
  the sheet shows the light stage of this commit.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import tempfile
from pathlib import Path

import matplotlib
import torch
from PIL import Image
from skimage import data

from kornia_ilum.color import linear_to_srgb
from kornia_ilum_lab.provenance import stamp_figure
from kornia_ilum.detection import create_detector, crop_faces, square_crop_boxes
from kornia_ilum.geometry import latlong_to_mirror_ball
from kornia_ilum.io import read_hdr
from kornia_ilum_lab.synth.environments import EnvironmentSampler, default_sources
from kornia_ilum_lab.synth.environments.real import HDRFolderSource
from kornia_ilum_lab.synth.lightstage.cache import SampledViews, Workers, build_cache
from kornia_ilum_lab.synth.lightstage.olat import render_olat
from kornia_ilum_lab.synth.lightstage.portraits import PortraitConfig, PortraitDataset, relight_portraits
from kornia_ilum_lab.synth.lightstage.preview import contact_sheet
from kornia_ilum_lab.synth.lightstage.scene import sample_views
from kornia_ilum_lab.synth.lightstage.settings import Auto, OnePass
from kornia_ilum_lab.synth.lightstage.subjects import subject_source, subject_split
from kornia_ilum_lab.synth.sheets import write_grid

matplotlib.use("Agg")

STATIC = Path(__file__).resolve().parents[1] / "_static"
#: What the figures show: the light stage (and, for the portraits, everything the dataset draws).
SHOWS = ("kornia_ilum_lab.synth",)
#: The training subjects of the portraits' sheet: one view each of the training seeds among these.
PORTRAIT_SEEDS = range(30)


def subjects_sheet(assets: str, count: int = 12) -> None:
    source = subject_source("makehuman", assets)
    out = STATIC / "subjects_contact_sheet.png"
    contact_sheet([source.sample(s) for s in range(count)], out, size=192, columns=6, spp=128, distance=0.75)
    image = Image.open(out).convert("RGB")  # 256 colours, undithered: under 300 KB
    image.quantize(256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(out, optimize=True)
    stamp_figure(out, command=COMMAND + " --only subjects", shows=SHOWS)
    print(f"wrote {out} ({out.stat().st_size // 1024} KiB)")


def _relit_face(field, lighting: torch.Tensor) -> torch.Tensor:
    image, _ = relight_portraits(field, lighting)
    image = image[0]
    x0, y0, x1, y1 = field.face_box.tolist()
    cx, cy, half = (x0 + x1) / 2, (y0 + y1) / 2, 0.7 * max(x1 - x0, y1 - y0)
    lo_x, lo_y = max(0, int(cx - half)), max(0, int(cy - half))
    crop = image[:, lo_y : int(cy + half), lo_x : int(cx + half)]
    subject = crop[:, crop.sum(0) > 0]
    return linear_to_srgb((crop * 0.18 / subject.mean().clamp(min=1e-6)).clamp(0, 1))


def subsurface_pair(assets: str, hdri: str, seed: int = 3) -> None:
    subject = subject_source("makehuman", assets).sample(seed)
    camera = dataclasses.replace(sample_views(seed, 4, size=256)[1], yaw_deg=20.0, pitch_deg=0.0,
                                 roll_deg=0.0)
    latlong = read_hdr(hdri).clamp(min=0)
    lighting = latlong_to_mirror_ball(latlong[None], 32).clamp(min=0)
    tiles = [_relit_face(render_olat(subject, camera, settings=OnePass(subsurface=flag)), lighting)
             for flag in (False, True)]
    out = STATIC / "subsurface_pair.png"
    write_grid(tiles, ["without subsurface", "with subsurface (screen-space diffusion)"],
               title=f"MakeHuman subject {seed} relit by {Path(hdri).name}", path=out, columns=2,
               cell=(3.0, 3.1), fontsize=8, dpi=100, palette=True)
    stamp_figure(out, command=COMMAND + " --only subsurface", shows=SHOWS)
    print(f"wrote {out} ({out.stat().st_size // 1024} KiB)")


def portraits_sheet(cache: str, hdri: list[str], count: int = 65, columns: int = 13) -> None:
    sources = default_sources() + [HDRFolderSource(h) for h in hdri]
    # one lighting per field and chunk, so the sheet shows many subject-views (training uses 16 per field)
    config = PortraitConfig(split="train", environments=EnvironmentSampler(sources, seed=0), lightings_per_field=1,
                            shuffle=1)
    samples = list(itertools.islice(iter(PortraitDataset(cache, config=config, seed=0)), count - 1))
    samples.sort(key=lambda s: int(s["skin_tone"]))

    def spheres(sample) -> torch.Tensor:
        sph = sample["spheres"]
        row = torch.cat([sph[f"{k}_32"] for k in ("diffuse", "matte_silver", "mirror")], dim=-1)
        return torch.nn.functional.interpolate(row[None].float(), scale_factor=256 / 96, mode="nearest")[0]

    tiles, captions = [], []
    photo = torch.from_numpy(data.astronaut()).permute(2, 0, 1).float() / 255
    boxes = create_detector().detect(photo[None])[0][:1, :4]  # the crop that inference makes (default detector)
    tiles.append(crop_faces(photo, square_crop_boxes(boxes))[0])
    captions.append("photograph (skimage astronaut)")
    for s in samples:
        img = s["image"].float() / 255
        sph = spheres(s)
        tiles.append(torch.cat([img, torch.ones(3, 6, 256), sph.clamp(0, 1)], dim=1))
        captions.append(f"s{s['subject_seed']} MST {s['skin_tone']} {s['label']}")
    tiles[0] = torch.cat([tiles[0], torch.ones(3, 6 + tiles[1].shape[1] - 262, 256)], dim=1)
    png = STATIC / "lightstage_contact_sheet.png"
    write_grid(tiles, captions,
               title="training portraits as PortraitDataset yields them | ground truth: diffuse, "
               "matte silver, mirror", path=png, columns=columns,
               cell=(1.45, 1.45 * tiles[1].shape[1] / 256 + 0.2), fontsize=5.0, dpi=72, palette=False)
    # 64 portraits do not fit a 300 KB PNG; the portraits are JPEG-compressed photographs anyway
    out = png.with_suffix(".jpg")
    Image.open(png).convert("RGB").save(out, quality=80, optimize=True)
    png.unlink()
    stamp_figure(out, command=COMMAND + " --only portraits", shows=SHOWS)
    print(f"wrote {out} ({out.stat().st_size // 1024} KiB)")


COMMAND = ("python docs/_scripts/make_lightstage_figures.py --assets ../shared/data/makehuman "
           "--hdri ../shared/data/hdri ../shared/data/hdri_more")


def fresh_cache(assets: str, folder: Path) -> str:
    """One view of each training subject of :data:`PORTRAIT_SEEDS`, rendered by today's light stage into
    ``folder``."""
    seeds = [s for s in PORTRAIT_SEEDS if subject_split(s) == "train"]
    build_cache(subject_source("makehuman", assets), seeds, out_dir=folder, renderer=Auto(),
                views=SampledViews(1, size=192),
                workers=Workers(processes=2), progress=True)
    return str(folder)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--assets", required=True, help="the MakeHuman assets folder")
    parser.add_argument("--hdri", nargs="*", default=[], help="folders of real HDR maps")
    parser.add_argument("--only", choices=("subjects", "subsurface", "portraits"), action="append")
    args = parser.parse_args()
    torch.set_num_threads(2)
    only = set(args.only or ("subjects", "subsurface", "portraits"))
    if "subjects" in only:
        subjects_sheet(args.assets)
    if "subsurface" in only:
        maps = sorted(itertools.chain.from_iterable(Path(h).glob("*.hdr") for h in args.hdri))
        subsurface_pair(args.assets, str(maps[0]) if maps else "")
    if "portraits" in only:
        with tempfile.TemporaryDirectory() as tmp:
            portraits_sheet(fresh_cache(args.assets, Path(tmp) / "cache"), args.hdri)


if __name__ == "__main__":
    main()
