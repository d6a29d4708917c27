"""``network.build``: a world by name or file -> NetworkBundle, cached by content hash.

The cache key is the SHA-256 of the validated line description (as canonical JSON), the world parameters,
:data:`network.generator.GENERATOR_VERSION` and the eclipse-sumo version, so any change to any of them
rebuilds. Built worlds live in ``$RAILSIM_CACHE/networks/<key>/`` (default ``~/.cache/railsim``); a hit only
reads the topology JSON (no netconvert, no sumolib). With ``out_dir`` the three files are copied there as
``<name>.net.xml``, ``<name>.stops.add.xml`` and ``<name>.topology.json``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

from network import generator
from network.line import LineDescription, load_description, parse_description
from network.topology import NetworkBundle, bundle_from_json
from network.worlds import describe_world, shipped_worlds
from railsim.errors import ConfigError


def cache_root() -> Path:
    base = os.environ.get("RAILSIM_CACHE")
    root = Path(base) if base else Path.home() / ".cache" / "railsim"
    return root / "networks"


def resolve(name_or_path: str | Path, **params: Any) -> LineDescription:
    """Load and validate the line description of a shipped world or a YAML file."""
    text = str(name_or_path)
    if isinstance(name_or_path, str) and text in shipped_worlds():
        raw, source = describe_world(text, **params)
        return parse_description(raw, source)
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.exists():
        if params:
            raise ConfigError(
                path,
                "params",
                f"expected no parameters for a description file (parameters "
                f"apply to shipped worlds), got {', '.join(params)}",
            )
        return load_description(path)[0]
    raise ConfigError(
        None,
        None,
        f"unknown world {text!r}: expected a line-description file (.yaml) or one of {', '.join(shipped_worlds())}",
    )


def _key(desc: LineDescription) -> str:
    payload = {
        "description": dataclasses.asdict(dataclasses.replace(desc, source="")),
        "generator": generator.GENERATOR_VERSION,
        "sumo": generator.sumo_version(),
    }
    blob = json.dumps(payload, sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:24]


def _load_cached(folder: Path, name: str) -> NetworkBundle | None:
    topo = folder / f"{name}.topology.json"
    try:
        data = json.loads(topo.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    bundle = bundle_from_json(data, folder, topo)
    if not (bundle.net_file.exists() and bundle.stops_file.exists()):
        return None
    return bundle


def build(name_or_path: str | Path, out_dir: Path | None = None, **params: Any) -> NetworkBundle:
    """Build (or fetch from the cache) a world and return its :class:`NetworkBundle`."""
    t0 = time.perf_counter()
    desc = resolve(name_or_path, **params)
    key = _key(desc)
    folder = cache_root() / key
    bundle = _load_cached(folder, desc.name)
    if bundle is None:
        folder.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{key}-", dir=folder.parent))
        try:
            generator.generate(desc, tmp, cache_key=key)
            try:
                os.replace(tmp, folder)  # atomic publish; another process may have won the race
            except OSError:
                if _load_cached(folder, desc.name) is None:
                    shutil.rmtree(folder, ignore_errors=True)
                    os.replace(tmp, folder)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        bundle = _load_cached(folder, desc.name)
        assert bundle is not None
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        for src in (bundle.net_file, bundle.stops_file, bundle.topology_file):
            shutil.copyfile(src, out / src.name)
        bundle = dataclasses.replace(
            bundle,
            net_file=out / bundle.net_file.name,
            stops_file=out / bundle.stops_file.name,
            topology_file=out / bundle.topology_file.name,
        )
    return dataclasses.replace(bundle, build_time_s=time.perf_counter() - t0)
