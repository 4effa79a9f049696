"""The repository's protocol (config.yaml) for tests that call code needing one."""

from pathlib import Path

import yaml

from embodied_snap.protocol import load
from embodied_snap.validate import Limits

CONFIG = Path(__file__).resolve().parent.parent / "config.yaml"
PROTO = load(yaml.safe_load(CONFIG.read_text()))
HOLD = yaml.safe_load(CONFIG.read_text())["twin"]["held_base"]  # the simulated operator's hold
LIMITS = Limits.from_config(yaml.safe_load(CONFIG.read_text()))  # the gate's limits
