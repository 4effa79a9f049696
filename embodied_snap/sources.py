"""Where each claimed number was read from: the artifact and the key inside it, recorded while the
number is computed (docs/lineage.md, "A number's lineage").

A stage's claims function reads its artifacts (parsed JSON) through `Traced` views and assigns
each claim to a `Claims` mapping; every leaf value read since the previous assignment is that
claim's source. So the source is taken where the number is made, never matched afterwards by name.
A key is the path of names inside the artifact joined by "/" (list positions are numbers):
`results/characterize/servo.json:rate_tick_s`, `results/dynamics/sealed/eval.json:seeds/0/at_s_mm/0.3`.
"""

from __future__ import annotations

SEP = ":"  # artifact:key


class Traced:
    """A read-only view of a JSON value (dict or list) that logs every leaf it hands out."""

    __slots__ = ("_v", "_art", "_key", "_log")

    def __init__(self, value, artifact: str, log: list, key: tuple = ()):
        self._v, self._art, self._key, self._log = value, artifact, key, log

    def _wrap(self, k, v):
        key = self._key + (str(k),)
        if isinstance(v, (dict, list)):
            return Traced(v, self._art, self._log, key)
        self._log.append((self._art, key))
        return v

    def __getitem__(self, k):
        return self._wrap(k, self._v[k])

    def get(self, k, default=None):
        if k in self._v:
            return self._wrap(k, self._v[k])
        self._log.append((self._art, self._key + (str(k),)))  # looked for there: the claim's place
        return default

    def __contains__(self, k):
        return k in self._v

    def __len__(self):
        self._log.append((self._art, self._key))  # a count is read from the container itself
        return len(self._v)

    def __iter__(self):
        if isinstance(self._v, dict):
            return iter(self._v)
        return (self._wrap(i, v) for i, v in enumerate(self._v))

    def keys(self):
        return self._v.keys()

    def items(self):
        return [(k, self._wrap(k, v)) for k, v in self._v.items()]

    def values(self):
        return [self._wrap(k, v) for k, v in self._v.items()]


def plain(v):
    """The JSON value behind a (perhaps nested) Traced view, every leaf logged as read; an empty
    container is read as itself."""
    if isinstance(v, Traced):
        if not v._v:
            v._log.append((v._art, v._key))
            return type(v._v)()
        return {k: plain(v[k]) for k in v._v} if isinstance(v._v, dict) else [plain(x) for x in v]
    if isinstance(v, dict):
        return {k: plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    return v


class Claims(dict):
    """claim id -> value, each with the (artifact, key) leaves read since the previous claim."""

    def __init__(self, log: list):
        super().__init__()
        self.log, self.sources = log, {}

    def __setitem__(self, cid, value):
        value = plain(value)  # a container handed over whole: its leaves are read here
        self.sources[cid] = sorted(set(self.log))
        self.log.clear()
        super().__setitem__(cid, value)


def named(artifacts: dict) -> dict:
    """name -> (path, value) (or a list of them); a bare value is named by its name (and a list of
    bare values name/0, name/1, ...)."""
    def one(name, a):
        return a if isinstance(a, tuple) else (name, a)

    return {k: [one(f"{k}/{i}", x) for i, x in enumerate(a)] if isinstance(a, list) else one(k, a)
            for k, a in artifacts.items()}


def trace(ours, artifacts: dict) -> tuple[dict, dict]:
    """Run `ours(views, out)` on Traced views of `artifacts` (name -> (path, JSON value), or
    name -> [(path, value), ...] for a list of artifacts): claim id -> value, claim id -> sources."""
    log: list = []
    views = {k: [Traced(v, p, log) for p, v in a] if isinstance(a, list) else Traced(a[1], a[0], log)
             for k, a in artifacts.items()}
    out = Claims(log)
    ours(views, out)
    return dict(out), {cid: source_text(s) for cid, s in out.sources.items()}


def _merge_once(keys: set[tuple]) -> set[tuple] | None:
    """The first set of keys equal but in one position (the lowest such position), merged as `*`
    there; None when there is none."""
    for i in range(max((len(k) for k in keys), default=0)):
        like: dict[tuple, set] = {}
        for k in sorted(keys):
            if len(k) > i:
                like.setdefault(k[:i] + ("*",) + k[i + 1:], set()).add(k)
        for pattern, ks in like.items():
            if len(ks) > 1:
                return (keys - ks) | {pattern}
    return None


def _merge(keys: list[tuple]) -> list[tuple]:
    """Keys equal but in one position merged as `*` there (every seed's value, every rule's)."""
    keys = set(keys)
    while (merged := _merge_once(keys)) is not None:
        keys = merged
    return sorted(keys)


def source_text(leaves) -> str:
    """`artifact:key` per source, space-separated; keys that differ in one place only merged by `*`."""
    by: dict[str, list] = {}
    for art, key in leaves:
        by.setdefault(art, []).append(key)
    return " ".join(f"{art}{SEP}{'/'.join(k)}" for art in sorted(by) for k in _merge(by[art]))


def parse_source(text: str) -> list[tuple[str, str]]:
    """[(artifact, key)] of a `source` cell."""
    out = []
    for s in (text or "").split():
        art, _, key = s.partition(SEP)
        out.append((art, key))
    return out


def read_key(value, key: str):
    """The value at `key` ("a/0/b"; "*" takes every element) of a JSON value."""
    if not key:
        return value
    head, _, rest = key.partition("/")
    if head == "*":
        items = value.values() if isinstance(value, dict) else value
        return [read_key(v, rest) for v in items]
    if isinstance(value, list):
        return read_key(value[int(head)], rest)
    if isinstance(value, dict) and head in value:
        return read_key(value[head], rest)
    raise KeyError(head)


# --- the recordings of a fit ---------------------------------------------------------------------

RECORDINGS = "recordings"  # the key of a fit's artifact that names the groups that entered it


def recordings(given, used, rule: str = "") -> dict:
    """What a fit's artifact records of its groups: those `used`, and those given but left out by
    the fit's own `rule`, each with it. A number's recordings are its fit's `used` groups."""
    used = sorted(set(used))
    return {"used": used, "dropped": {g: rule for g in sorted(set(given) - set(used))}}
