"""scripts/compare_speed.py exports another revision as a separate, importable package."""

import importlib
import subprocess
import sys
from pathlib import Path

import pytest

from tests._scripts import ROOT, load_script


def _script():
    return load_script("compare_speed")


@pytest.fixture()
def in_git_checkout() -> None:
    probe = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True, check=False)
    if probe.returncode != 0:
        pytest.skip("not a git checkout")


@pytest.mark.usefixtures("in_git_checkout")
def test_exported_revision_imports_only_itself(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """HEAD exported as mjnav_ref loads its own bundled stages and never imports mjnav."""
    ref = _script().export_revision("HEAD", tmp_path)
    assert ref
    sources = "\n".join(p.read_text() for p in (tmp_path / "mjnav_ref").rglob("*.py"))
    assert "from mjnav." not in sources and "import mjnav\n" not in sources
    monkeypatch.syspath_prepend(str(tmp_path))
    config = importlib.import_module("mjnav_ref.config")
    assert Path(config.__file__).is_relative_to(tmp_path)
    assert config.load_task("stage7").crowd.count == 30
    for name in [m for m in sys.modules if m == "mjnav_ref" or m.startswith("mjnav_ref.")]:
        monkeypatch.delitem(sys.modules, name)


@pytest.mark.usefixtures("in_git_checkout")
def test_unknown_revision_is_a_config_error(tmp_path: Path) -> None:
    """A ref git does not know gives a clear ConfigError, not a traceback from tar."""
    from mjnav.schema import ConfigError

    with pytest.raises(ConfigError, match="no-such-ref"):
        _script().export_revision("no-such-ref", tmp_path)
