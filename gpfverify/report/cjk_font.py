"""The CJK font embedded in report pages, so that the papers' Chinese titles, author names and
quotations render as characters on a machine without any CJK font (not as empty boxes).

The font is a subset of Noto Sans CJK (SIL Open Font License 1.1, ``fonts/OFL.txt``) holding only
the characters gpfverify's own text uses — every CJK character in the package's sources, where all
page text comes from — renamed ``gpfverify-cjk`` as the licence asks of a modified font. It is WOFF
(zlib, no extra dependency), a few tens of kilobytes, and a page carries it only when it contains a
CJK character (:func:`font_face_css`). Characters the subset lacks still fall back to the system's
CJK fonts named after it in the page's CSS; a test keeps the subset covering every character the
sources use.

To rebuild the subset after adding Chinese text (needs the full font, e.g. Debian's
``fonts-noto-cjk``; fontTools comes with matplotlib)::

    python -m gpfverify.report.cjk_font /usr/share/fonts/opentype/noto/NotoSansCJK-Regular.ttc
"""

from __future__ import annotations

import base64
import re
import sys
from functools import cache
from pathlib import Path

FAMILY = "gpfverify-cjk"
FONT = Path(__file__).parent / "fonts" / "gpfverify-cjk.woff"
PACKAGE = Path(__file__).parents[1]
#: CJK ideographs, CJK punctuation and full-width forms: the characters the subset is for
CJK_CHARACTER = re.compile(r"[\u3000-\u303f\u3400-\u4dbf\u4e00-\u9fff\uf900-\ufaff\uff00-\uffef]")
#: the face of Noto Sans CJK's collection whose glyphs are the simplified-Chinese forms
_SIMPLIFIED_CHINESE_FACE = "Noto Sans CJK SC"


def characters_used(package: Path = PACKAGE) -> set[str]:
    """Every CJK character in the sources under ``package`` (the text pages can show)."""
    return {ch for source in sorted(package.rglob("*.py"))
            for ch in CJK_CHARACTER.findall(source.read_text(encoding="utf-8"))}


@cache
def font_face_css() -> str:
    """The ``@font-face`` rule declaring :data:`FAMILY` from the embedded subset (a data URI)."""
    data = base64.b64encode(FONT.read_bytes()).decode("ascii")
    return (f'@font-face{{font-family:"{FAMILY}";font-display:swap;'
            f'src:url(data:font/woff;base64,{data}) format("woff")}}')


def page_needs_font(html_text: str) -> bool:
    return CJK_CHARACTER.search(html_text) is not None


def build_subset(collection: Path, out: Path = FONT, characters: set[str] | None = None) -> set[str]:
    """Write the WOFF subset of ``collection``'s simplified-Chinese face holding ``characters``
    (default: :func:`characters_used`), renamed :data:`FAMILY`; returns the characters it covers."""
    from fontTools.subset import Options, Subsetter  # type: ignore[import-untyped]
    from fontTools.ttLib import TTCollection  # type: ignore[import-untyped]

    wanted = characters_used() if characters is None else characters
    faces = TTCollection(str(collection)).fonts
    font = next(f for f in faces if f["name"].getDebugName(1) == _SIMPLIFIED_CHINESE_FACE)
    options = Options()
    options.flavor = "woff"
    options.layout_features = ["*"]
    options.name_IDs = [0, 13, 14]  # copyright and licence; the family names are set below
    subsetter = Subsetter(options)
    subsetter.populate(text="".join(sorted(wanted)))
    subsetter.subset(font)
    names = font["name"]
    for name_id, value in ((1, FAMILY), (2, "Regular"), (3, f"{FAMILY} subset"), (4, FAMILY), (6, FAMILY)):
        names.setName(value, name_id, 3, 1, 0x409)
    font.flavor = "woff"
    out.parent.mkdir(parents=True, exist_ok=True)
    font.save(str(out))
    return {chr(c) for c in font.getBestCmap()}


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print("usage: python -m gpfverify.report.cjk_font NotoSansCJK-Regular.ttc", file=sys.stderr)
        return 2
    wanted = characters_used()
    covered = build_subset(Path(argv[0]))
    missing = "".join(sorted(wanted - covered))
    print(f"{FONT}: {len(wanted & covered)} characters, {FONT.stat().st_size} bytes"
          + (f"; not in the font: {missing}" if missing else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
