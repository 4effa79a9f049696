"""Tiny file trees for the lineage tests: files whose content names them, so hashes differ."""


def write(root, rel, data=b"x"):
    p = root / rel
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_bytes(data)
    return rel


def group_files(root, gid, raw="raw_data"):
    """A raw group's three files (not valid recordings: lineage only looks at paths and hashes)."""
    return [write(root, f"{raw}/groups/{gid}/{f}", f"{gid}/{f}".encode())
            for f in ("mocap.parquet", "servo.parquet", "meta.json")]
