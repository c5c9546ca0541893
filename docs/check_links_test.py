#!/usr/bin/env python3
"""Tests of docs/check_links.py on small fixtures: a sound book passes, and every kind of broken
link it must catch is caught. Run by .ci/run before the book is built:

    python3 docs/check_links_test.py
"""

import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import check_links  # noqa: E402


def write(root, rel, text):
    path = os.path.join(root, rel)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w", encoding="utf-8") as f:
        f.write(text)


class Fixture:
    """A repository with README.md, docs/src/guide/a.md and its built book docs/book/."""

    def __init__(self, readme, page_a, page_b):
        self.dir = tempfile.TemporaryDirectory()
        self.root = self.dir.name
        write(self.root, "README.md", readme)
        write(self.root, "docs/src/guide/a.md", "# A\n\n## Section one\n")
        write(self.root, "docs/src/guide/b.md", "# B\n")
        write(self.root, "CHANGELOG.md", "# Changelog\n\n## [0.8.0] - 2026-11-27\n")
        write(self.root, "docs/book/index.html", '<a href="guide/a.html">A</a>')
        write(self.root, "docs/book/guide/a.html", page_a)
        write(self.root, "docs/book/guide/b.html", page_b)
        write(self.root, "docs/book/images/x.png", "png")

    def problems(self):
        book = os.path.join(self.root, "docs", "book")
        src = os.path.join(self.root, "docs", "src")
        readme = os.path.join(self.root, "README.md")
        return check_links.check_book(book) + check_links.check_markdown(readme, self.root, book, src)


GOOD_A = '<h1 id="a">A</h1><h2 id="section-one">Section one</h2><a href="#a">top</a><img src="../images/x.png">'
GOOD_B = '<h1 id="b">B</h1><a href="a.html#section-one">A</a><a href="https://example.org/#x">out</a>'
GOOD_README = (
    "# R\n\n## Here\n\n[a](docs/src/guide/a.md#section-one) [b](docs/src/guide/b.md) [me](#here)\n"
    "[log](CHANGELOG.md#080---2026-11-27) [web](https://example.org)\n"
    "```sh\n[not a link](nowhere.md)\n```\n`[nor this](nowhere.md)`\n"
)


class CheckLinks(unittest.TestCase):
    def fixture(self, readme, page_a, page_b):
        f = Fixture(readme, page_a, page_b)
        self.addCleanup(f.dir.cleanup)
        return f

    def test_a_sound_book_and_readme_pass(self):
        self.assertEqual(self.fixture(GOOD_README, GOOD_A, GOOD_B).problems(), [])

    def test_a_missing_anchor_in_another_page_fails(self):
        f = self.fixture(GOOD_README, GOOD_A, GOOD_B.replace("#section-one", "#section-two"))
        p = f.problems()
        self.assertEqual(len(p), 1, p)
        self.assertIn("no id 'section-two'", p[0])

    def test_a_missing_anchor_in_the_same_page_fails(self):
        p = self.fixture(GOOD_README, GOOD_A.replace('href="#a"', 'href="#nowhere"'), GOOD_B).problems()
        self.assertEqual(len(p), 1, p)
        self.assertIn("'#nowhere'", p[0])

    def test_a_missing_page_or_image_fails(self):
        a = GOOD_A.replace("../images/x.png", "../images/y.png")
        b = GOOD_B.replace("a.html#section-one", "c.html")
        p = self.fixture(GOOD_README, a, b).problems()
        self.assertEqual(len(p), 2, p)
        self.assertTrue(all("no such file in the book" in x for x in p), p)

    def test_a_link_out_of_the_book_fails(self):
        p = self.fixture(GOOD_README, GOOD_A, GOOD_B + '<a href="../../Cargo.toml">c</a>').problems()
        self.assertEqual(len(p), 1, p)
        self.assertIn("leaves the book", p[0])

    def test_readme_links_to_missing_files_and_anchors_fail(self):
        readme = GOOD_README.replace("guide/b.md", "guide/c.md").replace("#section-one", "#section-9")
        readme += "[up](../elsewhere/x.md) [gone](#nowhere) [log](CHANGELOG.md#090)\n"
        p = self.fixture(readme, GOOD_A, GOOD_B).problems()
        self.assertEqual(len(p), 5, p)
        joined = "\n".join(p)
        for bit in ("guide/c.md", "#section-9", "outside the repository", "#nowhere", "#090"):
            self.assertIn(bit, joined)


if __name__ == "__main__":
    unittest.main(verbosity=1)
