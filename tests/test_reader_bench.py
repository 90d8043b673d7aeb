"""The readers' benchmark: words listed by hand are counted in string literals, not docstrings."""

from tabletop.reader.bench import BENCH_REQUESTS, listed_words


def test_listed_words_counts_literals_but_not_docstrings(tmp_path):
    f = tmp_path / "m.py"
    f.write_text(
        '"""Module words: alpha beta."""\n'
        'WORDS = ("gamma delta", "delta")\n'
        "def f():\n"
        '    """Docstring words: epsilon."""\n'
        '    return "zeta x"\n'
    )
    assert listed_words(f) == 3  # gamma, delta, zeta ("x" is too short)
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "a.py").write_text('A = ("gamma", "eta")\n')
    (tmp_path / "pkg" / "b.py").write_text('B = "theta eta"\n')
    assert listed_words(tmp_path / "pkg") == 3  # a package counts each word once


def test_the_benchmark_requests_are_the_projects_own():
    assert len(BENCH_REQUESTS) == len(set(BENCH_REQUESTS)) >= 10
