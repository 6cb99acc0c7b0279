"""The documentation's links: every relative link in README.md, MODEL_CARD.md and docs/*.md names a
file that exists and, with a #fragment into a Markdown file, a heading of that file (GitHub's
anchor rules); external links are checked for syntax only, never fetched. And the README stays a
front door: at most 400 lines, opening with the install-and-render and test commands."""

import re
import unicodedata
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

ROOT = Path(__file__).resolve().parents[2]
README_MAX_LINES = 400
DOCS = sorted(
    [ROOT / "README.md", ROOT / "MODEL_CARD.md", *(ROOT / "docs").glob("*.md")],
    key=lambda p: p.relative_to(ROOT).as_posix(),
)

FENCE = re.compile(r"^\s*(`{3,}|~{3,})")
ATX_HEADING = re.compile(r"^ {0,3}(#{1,6})(?:[ \t]+(.*?))?(?:[ \t]+#+)?[ \t]*$")
SETEXT_UNDERLINE = re.compile(r"^ {0,3}(=+|-+)[ \t]*$")
HTML_ANCHOR = re.compile(r"<a\s[^>]*?(?:name|id)\s*=\s*[\"']([^\"']+)[\"']", re.IGNORECASE)
CODE_SPAN = re.compile(r"(`+)(.+?)(?<!`)\1(?!`)", re.DOTALL)
# [text](dest "title") and ![alt](dest); the text may hold one level of brackets.
INLINE_LINK = re.compile(
    r"!?\[((?:[^\[\]]|\[[^\[\]]*\])*)\]\(\s*(<[^<>\n]*>|[^\s()<>]*(?:\([^\s()]*\)[^\s()<>]*)*)"
    r"(?:\s+(?:\"[^\"]*\"|'[^']*'|\([^()]*\)))?\s*\)"
)
REFERENCE_DEFINITION = re.compile(r"^ {0,3}\[[^\]]+\]:\s*(<[^<>\n]*>|\S+)")
AUTOLINK = re.compile(r"<((?:https?|mailto):[^<>\s]*)>")
LINE_ANCHOR = re.compile(r"^L\d+(?:C\d+)?(?:-L\d+(?:C\d+)?)?$")


def github_slug(text):
    """The anchor GitHub gives a heading's text: inline markup reduced to its text, lowercase,
    everything but letters, digits, marks, '_', '-' and spaces dropped, each space a '-'."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", text)  # links and images: their text
    text = re.sub(r"<[^>]+>", "", text)  # inline HTML tags
    text = text.lower()
    kept = []
    for ch in text:
        cat = unicodedata.category(ch)
        if ch in " -_" or cat[0] in "LMN":
            kept.append(ch)
    return "".join(kept).replace(" ", "-")


def _blocks(lines):
    """Split a Markdown file into runs of text lines outside fenced code, as (first line number,
    lines); a blank line ends a run (code spans never cross one)."""
    runs, current, start, fence = [], [], 0, None
    for number, line in enumerate(lines, 1):
        m = FENCE.match(line)
        if fence is not None:
            # A fence closes on a line of the same character, at least as long, and nothing else.
            closes = m and m.group(1)[0] == fence[0] and len(m.group(1)) >= len(fence)
            if closes and not line.strip()[len(m.group(1)):].strip():
                fence = None
            continue
        if m:
            fence = m.group(1)
            if current:
                runs.append((start, current))
            current = []
            continue
        if not line.strip():
            if current:
                runs.append((start, current))
            current = []
            continue
        if not current:
            start = number
        current.append(line)
    if current:
        runs.append((start, current))
    return runs


def anchors(path):
    """Every anchor a Markdown file defines: its headings' slugs (a repeated slug gets -1, -2,
    ... in order, as GitHub numbers them) and explicit <a name|id="...">."""
    seen, found = {}, set()
    for _, run in _blocks(path.read_text(encoding="utf-8").split("\n")):
        for i, line in enumerate(run):
            text = None
            m = ATX_HEADING.match(line)
            if m:
                text = m.group(2) or ""
            elif i > 0 and SETEXT_UNDERLINE.match(line) and not run[i - 1].lstrip().startswith(
                    ("|", "-", "*", "+", ">", "#")):
                text = run[i - 1].strip()
            if text is not None:
                base = github_slug(CODE_SPAN.sub(lambda c: c.group(2).strip(), text).strip())
                n = seen.get(base, 0)
                found.add(base if n == 0 else f"{base}-{n}")
                seen[base] = n + 1
            found.update(HTML_ANCHOR.findall(line))
    return found


def links(path):
    """(line number, destination) of every link in a Markdown file, outside code."""
    out = []
    for start, run in _blocks(path.read_text(encoding="utf-8").split("\n")):
        text = "\n".join(run)
        # Code spans become placeholders of the same line count, so links inside them are not
        # links and a link whose text is code still matches.
        text = CODE_SPAN.sub(lambda c: "code" + "\n" * c.group(0).count("\n"), text)
        found = [(m.start(), m.group(2)) for m in INLINE_LINK.finditer(text)]
        found += [(m.start(), m.group(1)) for m in AUTOLINK.finditer(text)]
        offset = 0
        for line in text.split("\n"):
            m = REFERENCE_DEFINITION.match(line)
            if m:
                found.append((offset, m.group(1)))
            offset += len(line) + 1
        for pos, dest in sorted(found):
            if dest.startswith("<") and dest.endswith(">"):
                dest = dest[1:-1]
            out.append((start + text.count("\n", 0, pos), dest))
    return out


def _is_external(dest):
    return re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:", dest) is not None


def check_relative(path, root=ROOT):
    """Problems with the relative links of one Markdown file, one line each."""
    problems, cache = [], {}
    name = path.relative_to(root).as_posix()
    for number, dest in links(path):
        if _is_external(dest):
            continue
        where = f"{name}:{number}: ({dest})"
        if not dest:
            problems.append(f"{where}: empty link")
            continue
        target_part, _, fragment = dest.partition("#")
        target_part = unquote(target_part)
        if target_part.startswith("/"):
            problems.append(f"{where}: absolute path; links must be relative to the file")
            continue
        target = (path.parent / target_part).resolve() if target_part else path
        try:
            target.relative_to(root.resolve())
        except ValueError:
            problems.append(f"{where}: points outside the repository")
            continue
        if not target.exists():
            problems.append(f"{where}: {target_part} does not exist")
            continue
        if not fragment:
            continue
        if target.suffix.lower() == ".md" and target.is_file():
            if target not in cache:
                cache[target] = anchors(target)
            if unquote(fragment) not in cache[target]:
                problems.append(
                    f"{where}: no heading of {target.relative_to(root.resolve()).as_posix()} "
                    f"has the anchor #{fragment}"
                )
        elif not (target.is_file() and LINE_ANCHOR.match(fragment)):
            problems.append(f"{where}: #{fragment} into a file that is not Markdown")
    return problems


def check_external(path, root=ROOT):
    """Problems with the syntax of the external links of one Markdown file (nothing is fetched)."""
    problems = []
    name = path.relative_to(root).as_posix()
    for number, dest in links(path):
        if not _is_external(dest):
            continue
        where = f"{name}:{number}: ({dest})"
        parts = urlsplit(dest)
        if parts.scheme == "mailto":
            if "@" not in parts.path:
                problems.append(f"{where}: a mailto link without an address")
        elif parts.scheme not in ("http", "https"):
            problems.append(f"{where}: scheme {parts.scheme!r} is neither http(s) nor mailto")
        elif not parts.hostname or not (
                "." in parts.hostname or parts.hostname == "localhost") or re.search(r"\s", dest):
            problems.append(f"{where}: not a well-formed http(s) address")
    return problems


def _ids(paths):
    return [p.relative_to(ROOT).as_posix() for p in paths]


@pytest.mark.parametrize("doc", DOCS, ids=_ids(DOCS))
def test_relative_links_resolve(doc):
    problems = check_relative(doc)
    assert not problems, "broken links:\n" + "\n".join(problems)


@pytest.mark.parametrize("doc", DOCS, ids=_ids(DOCS))
def test_external_links_are_well_formed(doc):
    problems = check_external(doc)
    assert not problems, "malformed links:\n" + "\n".join(problems)


def test_readme_is_a_front_door_of_at_most_400_lines():
    n = len((ROOT / "README.md").read_text(encoding="utf-8").splitlines())
    assert n <= README_MAX_LINES, (
        f"README.md has {n} lines; move reference text into a page of docs/ and link it"
    )


def test_readme_opens_with_the_render_and_test_commands():
    lines = (ROOT / "README.md").read_text(encoding="utf-8").split("\n")
    opening = next(i for i, line in enumerate(lines) if FENCE.match(line))
    closing = next(i for i in range(opening + 1, len(lines)) if FENCE.match(lines[i]))
    commands = [line for line in lines[opening + 1:closing] if line.strip()]
    assert len(commands) == 2, commands
    install, render = commands[0].split(" && ")
    assert install == (
        "cargo install --locked --path crates/uwnr-cli --no-default-features --features bundled-model"
    )
    assert render.startswith("uwnr render assets/samples/")
    assert commands[1] == "cargo test --workspace --locked"
    after = next(line for line in lines[closing + 1:] if line.strip())
    assert after.startswith("To add training (`uwnr train`"), after


def test_readme_links_every_page_of_docs():
    linked = {
        (ROOT / dest.partition("#")[0]).resolve()
        for _, dest in links(ROOT / "README.md")
        if not _is_external(dest)
    }
    unlinked = [p.name for p in sorted((ROOT / "docs").glob("*.md")) if p.resolve() not in linked]
    assert not unlinked, f"pages of docs/ the README's map does not link: {unlinked}"


def test_github_anchor_rules():
    assert github_slug("Rendering: `uwnr render`") == "rendering-uwnr-render"
    assert github_slug("Beyond one machine: shards, Slurm, Kubernetes") == (
        "beyond-one-machine-shards-slurm-kubernetes"
    )
    assert github_slug("bf16 products (`--precision bf16`)") == "bf16-products---precision-bf16"
    assert github_slug("The bundled GAN baseline (uwgan-default)") == (
        "the-bundled-gan-baseline-uwgan-default"
    )
    assert github_slug("Re-run with the depth policy of #27") == (
        "re-run-with-the-depth-policy-of-27"
    )
    assert github_slug("What [the card](MODEL_CARD.md) says") == "what-the-card-says"


def test_a_broken_link_or_anchor_is_reported(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "page.md").write_text(
        "# Page\n\n## Depth\n\ntext\n\n## Depth\n\n### `uwnr render`: options\n\n"
        "```sh\n# not a heading\n[not](a-link.md)\n```\n",
        encoding="utf-8",
    )
    (tmp_path / "README.md").write_text(
        "# Front\n\n"
        "[ok](docs/page.md) [ok](docs/page.md#depth) [ok](docs/page.md#depth-1)\n"
        "[ok](docs/page.md#uwnr-render-options) [ok](#front) `[code](missing.md)`\n"
        "[gone](docs/missing.md) [anchor](docs/page.md#depth-2)\n"
        "[wrapped `code\nspan`](docs/page.md#not-a-heading) [abs](/docs/page.md)\n"
        "[web](https://example.org/a#b) [bad](https:/example.org) [bad](ftp://example.org/x)\n",
        encoding="utf-8",
    )
    relative = check_relative(tmp_path / "README.md", root=tmp_path)
    assert len(relative) == 4, relative
    assert "README.md:5: (docs/missing.md): docs/missing.md does not exist" in relative
    assert any(p.startswith("README.md:5: (docs/page.md#depth-2): no heading") for p in relative)
    assert any(p.startswith("README.md:6: (docs/page.md#not-a-heading)") for p in relative)
    assert any(p.startswith("README.md:7: (/docs/page.md): absolute path") for p in relative)
    external = check_external(tmp_path / "README.md", root=tmp_path)
    assert len(external) == 2, external
    assert "README.md:8: (https:/example.org): not a well-formed" in external[0]
    assert "scheme 'ftp'" in external[1]
