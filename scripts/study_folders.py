"""Where the committed studies live: studies/<question>/<study>/ (one folder per question, its screens
inside), each screen a `tsrl report` folder (results.csv, experiment.json, figures). The one place
the scripts that read committed studies take this layout from."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
STUDIES = ROOT / "studies"


def screen_folders(root: Path = STUDIES) -> list[Path]:
    """Every screen folder under root/<question>/ (one holding a results.csv), sorted by screen name."""
    return sorted((p.parent for p in root.glob("*/*/results.csv")), key=lambda p: p.name)


def screen_folder(name: str, root: Path = STUDIES) -> Path:
    """The screen folder called `name` under root/<question>/; exits naming the screens if none is."""
    found = [p for p in root.glob(f"*/{name}") if p.is_dir()]
    if len(found) != 1:
        known = ", ".join(p.name for p in screen_folders(root))
        raise SystemExit(f"{root}: no single screen folder {name!r} (found {len(found)}); screens: {known}")
    return found[0]
