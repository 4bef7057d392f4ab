"""The README's Python snippet, run on a small generated mesh so the README stays true."""
import re


def test_readme_python_snippet_runs(source_dir, tmp_path):
    import incise

    readme = (source_dir / "README.md").read_text()
    snippet = re.search(r"```python\n(import incise\n.*?)```", readme, re.S).group(1)
    path = str(tmp_path / "organ.vtu")
    incise.write(incise.generate_ellipsoid((0.06, 0.04, 0.03), 3), path)
    scope = {}
    exec(snippet.replace('"demo-out/liver.vtu"', repr(path)), scope)
    assert scope["report"]["schema"] == "incise.quality/1"
    assert scope["stats"]["info"] == "success"
    assert scope["u"][:, 2].min() < 0  # pushed down
