"""The repository's protocol (config.yaml) for tests that call code needing one."""

from pathlib import Path

import yaml

from embodied_snap.protocol import load

CONFIG = Path(__file__).resolve().parent.parent / "config.yaml"
PROTO = load(yaml.safe_load(CONFIG.read_text()))
HOLD = yaml.safe_load(CONFIG.read_text())["twin"]["held_base"]  # the simulated operator's hold
