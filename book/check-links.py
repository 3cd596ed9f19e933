#!/usr/bin/env python3
"""Checks the relative links of the built book (run `mdbook build book` first).

Walks book/book/**/*.html and reports every relative link (href or src) to a file that does
not exist, or to an anchor (#id) that the target page does not define. External links
(http:, https:, mailto:, ...) are not followed. Exit status 1 when anything is broken.

    python3 book/check-links.py [BUILD_DIR]     (default: book/book next to this script)
"""

import html.parser
import os
import sys
import urllib.parse


class Page(html.parser.HTMLParser):
    """The links and the anchor ids of one HTML page."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.links = []  # (attribute value, line)
        self.ids = set()

    def handle_starttag(self, tag, attrs):
        for name, value in attrs:
            if value is None:
                continue
            if name in ("id", "name") and (name == "id" or tag == "a"):
                self.ids.add(value)
            if (name == "href" and tag in ("a", "link", "area")) or (
                name == "src" and tag in ("img", "script", "iframe", "source")
            ):
                self.links.append((value, self.getpos()[0]))


def parse(path, cache):
    if path not in cache:
        page = Page()
        with open(path, encoding="utf-8") as f:
            page.feed(f.read())
        cache[path] = page
    return cache[path]


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "book"))
    if not os.path.isdir(root):
        sys.exit(f"{root}: no built book here (run `mdbook build book` first)")
    pages = sorted(
        os.path.join(d, f)
        for d, _, files in os.walk(root)
        for f in files
        if f.endswith(".html")
    )
    cache = {}
    broken = []
    checked = 0
    for page_path in pages:
        page = parse(page_path, cache)
        for link, line in page.links:
            url = urllib.parse.urlsplit(link)
            if url.scheme or url.netloc or link.startswith("//"):
                continue  # external
            checked += 1
            where = f"{os.path.relpath(page_path, root)}:{line}"
            if url.path:
                target = os.path.normpath(
                    os.path.join(os.path.dirname(page_path), urllib.parse.unquote(url.path))
                )
                if url.path.endswith("/") or os.path.isdir(target):
                    target = os.path.join(target, "index.html")
                if not os.path.isfile(target):
                    broken.append(f"{where}: {link}: no file {os.path.relpath(target, root)}")
                    continue
            else:
                target = page_path
            fragment = urllib.parse.unquote(url.fragment)
            if fragment and target.endswith(".html"):
                if fragment not in parse(target, cache).ids:
                    broken.append(
                        f"{where}: {link}: no anchor #{fragment} in "
                        f"{os.path.relpath(target, root)}"
                    )
    for b in broken:
        print(b)
    print(
        f"{len(pages)} pages, {checked} relative links checked, {len(broken)} broken",
        file=sys.stderr,
    )
    sys.exit(1 if broken else 0)


if __name__ == "__main__":
    main()
