#!/usr/bin/env python3
"""Link and anchor check of the manual (run by .ci/run after `mdbook build docs`).

Fails (exit 1) on
- a relative link or image in the built book (docs/book/**/*.html) to a file the book does not
  have, or to an `#anchor` that is no id in the page it names (the same page for `#anchor` alone);
- a relative link or image in README.md to a file of the repository that does not exist, or to an
  `#anchor` its page does not have (a page of the book is looked up in the built book, so the
  anchor is mdBook's; another Markdown file by its headings).

Links with a scheme (https:, mailto:) are not followed: the check needs no network. Standard
library only.

    python3 docs/check_links.py [--root DIR]     # DIR: the repository (default: this file's ..)
"""

import argparse
import html.parser
import os
import re
import sys
import urllib.parse

SKIP_PAGES = {"404.html"}  # mdBook's 404 page links by the site's absolute URL


class _Page(html.parser.HTMLParser):
    """The ids a page defines and the (href, line) pairs it links to."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.ids = set()
        self.links = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        for key in ("id", "name"):
            if a.get(key) and (key == "id" or tag == "a"):
                self.ids.add(a[key])
        for key in ("href", "src"):
            if a.get(key) is not None and tag in ("a", "img"):
                self.links.append((a[key], self.getpos()[0]))


def _parse(path, cache={}):
    if path not in cache:
        p = _Page()
        with open(path, encoding="utf-8") as f:
            p.feed(f.read())
        cache[path] = p
    return cache[path]


def _is_external(url):
    return bool(re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:", url)) or url.startswith("//")


def check_book(book):
    """Problems of the built book at `book`, as 'file:line: message' strings."""
    problems = []
    book = os.path.abspath(book)
    for root, _, files in os.walk(book):
        for name in sorted(files):
            if not name.endswith(".html") or name in SKIP_PAGES:
                continue
            page = os.path.join(root, name)
            rel = os.path.relpath(page, book)
            for url, line in _parse(page).links:
                if not url or _is_external(url):
                    continue
                path, _, frag = url.partition("#")
                path = urllib.parse.unquote(path)
                frag = urllib.parse.unquote(frag)
                if path.startswith("/"):
                    problems.append(f"{rel}:{line}: absolute link {url!r}")
                    continue
                target = os.path.normpath(os.path.join(root, path)) if path else page
                if os.path.isdir(target):
                    target = os.path.join(target, "index.html")
                if not target.startswith(book + os.sep):
                    problems.append(f"{rel}:{line}: {url!r} leaves the book")
                elif not os.path.isfile(target):
                    problems.append(f"{rel}:{line}: {url!r}: no such file in the book")
                elif frag and target.endswith(".html") and frag not in _parse(target).ids:
                    problems.append(f"{rel}:{line}: {url!r}: no id {frag!r} in {os.path.relpath(target, book)}")
    return problems


def _heading_id(text):
    """GitHub's (and mdBook's) id of a Markdown heading."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text).replace("`", "").replace("*", "")
    return "".join(
        c if (c.isalnum() or c in "_-") else "-" if c.isspace() else "" for c in text.strip().lower()
    )


def _markdown_ids(path):
    ids, fence = set(), False
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.lstrip().startswith("```"):
                fence = not fence
            m = None if fence else re.match(r"#{1,6} (.*)", line)
            if m:
                i, k = _heading_id(m.group(1)), 1
                base = i
                while i in ids:
                    i, k = f"{base}-{k}", k + 1
                ids.add(i)
    return ids


def markdown_links(path):
    """(url, line) of every inline link and image of a Markdown file, outside code."""
    out, fence = [], False
    with open(path, encoding="utf-8") as f:
        for n, line in enumerate(f, 1):
            if line.lstrip().startswith("```"):
                fence = not fence
                continue
            if fence:
                continue
            line = re.sub(r"`[^`]*`", "", line)
            for m in re.finditer(r"\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)", line):
                out.append((m.group(1), n))
    return out


def check_markdown(md, root, book, src):
    """Problems of the relative links of the Markdown file `md` (README.md) of the repository."""
    problems = []
    root, book, src = (os.path.abspath(x) for x in (root, book, src))
    rel = os.path.relpath(md, root)
    for url, line in markdown_links(md):
        if _is_external(url):
            continue
        path, _, frag = url.partition("#")
        path = urllib.parse.unquote(path)
        target = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(md)), path)) if path else os.path.abspath(md)
        if not (target == root or target.startswith(root + os.sep)):
            problems.append(f"{rel}:{line}: {url!r} points outside the repository")
        elif not os.path.exists(target):
            problems.append(f"{rel}:{line}: {url!r}: no such file")
        elif frag:
            if target.startswith(src + os.sep) and target.endswith(".md"):
                built = os.path.join(book, os.path.relpath(target, src)[:-3] + ".html")
                ids = _parse(built).ids if os.path.isfile(built) else set()
            elif target.endswith(".md"):
                ids = _markdown_ids(target)
            else:
                ids = set()
            if frag not in ids:
                problems.append(f"{rel}:{line}: {url!r}: no such anchor")
    return problems


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--root", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    a = ap.parse_args(argv)
    root = os.path.abspath(a.root)
    book, src = os.path.join(root, "docs", "book"), os.path.join(root, "docs", "src")
    if not os.path.isfile(os.path.join(book, "index.html")):
        print(f"check_links: no built book in {book}: run `mdbook build docs` first", file=sys.stderr)
        return 1
    problems = check_book(book) + check_markdown(os.path.join(root, "README.md"), root, book, src)
    for p in problems:
        print(f"broken link: {p}", file=sys.stderr)
    pages = sum(len([f for f in fs if f.endswith(".html")]) for _, _, fs in os.walk(book))
    print(f"check_links: {pages} pages of the book and README.md: {len(problems)} broken link(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
