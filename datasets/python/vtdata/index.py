"""The sample index of a split, from ``manifest.json`` and the shards' summary sections.

Every sample of a snapshot shard is one chunk at log time ``index * SAMPLE_PERIOD_NS``; every
camera frame of an episode shard (its ``vtgen.shard`` metadata has an ``episode`` key) is one chunk,
frame ``k`` by start time being the sample ``first_sample + k`` (FORMAT.md, "Episodes"). The index
is read from the chunk indexes of each shard's summary, without scanning the data, and checked
against the manifest: no sample twice, none missing, each shard of this dataset and split.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple

from mcap.reader import make_reader

from .errors import DatasetError, DatasetNotFoundError
from .format import (
    EPISODE_METADATA_KEY,
    FORMAT_VERSION,
    MANIFEST_FILE,
    MANIFEST_FORMAT,
    SAMPLE_PERIOD_NS,
    SHARD_METADATA,
)

#: (split index, chunk start log time, chunk end log time) of one chunk of a shard.
_Located = Tuple[int, int, int]


def _read_manifest(root: Path) -> Dict[str, Any]:
    path = root / MANIFEST_FILE
    if not path.is_file():
        if not root.is_dir():
            raise DatasetNotFoundError(f"dataset folder {root} does not exist")
        raise DatasetNotFoundError(f"{path} is missing: {root} is not a vtgen dataset")
    try:
        with open(path, "r", encoding="utf-8") as f:
            manifest = json.load(f)
    except json.JSONDecodeError as e:
        raise DatasetError(f"{path} is not valid JSON: {e}") from e
    if not isinstance(manifest, dict) or manifest.get("format") != MANIFEST_FORMAT:
        found = manifest.get("format") if isinstance(manifest, dict) else type(manifest).__name__
        raise DatasetError(f"{path}: format is {found!r}, expected {MANIFEST_FORMAT!r}")
    version = manifest.get("format_version")
    if not isinstance(version, int) or version < 1:
        raise DatasetError(f"{path}: invalid format_version {version!r}")
    if version > FORMAT_VERSION:
        # stacklevel 3: the code that opened the Dataset (Dataset.__init__ calls this).
        warnings.warn(
            f"{path}: format_version {version} is newer than this reader ({FORMAT_VERSION}); "
            "unknown fields are ignored",
            stacklevel=3,
        )
    return manifest


def _check_shard_belongs(
    shard: str,
    meta: Optional[Mapping[str, str]],
    split: str,
    entry: Mapping[str, Any],
    manifest: Mapping[str, Any],
) -> None:
    """The shard's ``vtgen.shard`` metadata names this dataset (its config hash), split and shard."""
    if meta is None:
        raise DatasetError(f"{shard}: no '{SHARD_METADATA}' metadata record: not a vtgen shard")
    theirs, ours = meta.get("config_sha256"), manifest.get("config_sha256")
    if ours is not None and theirs != ours:
        raise DatasetError(
            f"{shard}: this shard belongs to another dataset (its config_sha256 is {theirs}, "
            f"the manifest's {ours})"
        )
    where = (meta.get("split"), meta.get("shard_index"))
    want = (split, str(entry.get("shard_index")))
    if entry.get("shard_index") is not None and where != want:
        raise DatasetError(
            f"{shard}: holds shard {where[1]} of split {where[0]!r}, but the manifest lists it "
            f"as shard {want[1]} of split {want[0]!r}"
        )


def _episode_record(shard: str, meta: Mapping[str, str]) -> Optional[Dict[str, Any]]:
    """The shard's ``vtgen.shard`` ``episode`` record (JSON), ``None`` in a snapshot shard."""
    raw = meta.get(EPISODE_METADATA_KEY)
    if raw is None:
        return None
    try:
        record = json.loads(raw)
    except json.JSONDecodeError as e:
        raise DatasetError(
            f"{shard}: {SHARD_METADATA} '{EPISODE_METADATA_KEY}' is not valid JSON: {e}"
        ) from e
    if not isinstance(record, dict):
        raise DatasetError(
            f"{shard}: {SHARD_METADATA} '{EPISODE_METADATA_KEY}' is not a JSON object"
        )
    return record


def _read_shard_summary(shard: str) -> Tuple[Any, Optional[Mapping[str, str]]]:
    """The shard's MCAP summary section and its ``vtgen.shard`` metadata (``None`` if absent)."""
    with open(shard, "rb") as f:
        try:
            reader = make_reader(f)
            summary = reader.get_summary()
            metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        except Exception as e:
            raise DatasetError(
                f"{shard}: cannot read the MCAP summary (truncated or damaged file?): {e}"
            ) from e
    if summary is None:
        raise DatasetError(f"{shard}: MCAP file has no summary section")
    return summary, metadata.get(SHARD_METADATA)


def _snapshot_chunks(shard: str, summary: Any) -> List[_Located]:
    """A snapshot shard's chunks: each one sample at a multiple of the sample period."""
    located: List[_Located] = []
    for chunk in summary.chunk_indexes:
        start, end = chunk.message_start_time, chunk.message_end_time
        if start % SAMPLE_PERIOD_NS != 0 or end != start:
            raise DatasetError(
                f"{shard}: chunk at offset {chunk.chunk_start_offset} spans log times "
                f"{start}..{end} ns; every chunk must hold exactly one sample at a multiple "
                f"of {SAMPLE_PERIOD_NS} ns"
            )
        located.append((start // SAMPLE_PERIOD_NS, start, end))
    return located


def _episode_chunks(
    shard: str,
    summary: Any,
    meta: Mapping[str, str],
    entry: Mapping[str, Any],
    episode: Mapping[str, Any],
) -> Tuple[List[_Located], Dict[str, Any]]:
    """An episode shard's chunks and its entry of :attr:`Dataset.episodes`.

    Its chunks in time order are its frames, numbered from ``first_sample``. Their time spans must
    not overlap, so a frame's time range selects its chunk alone.
    """
    first = meta.get("first_sample", entry.get("first_sample"))
    try:
        first = int(first)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise DatasetError(f"{shard}: episode shard without a valid first_sample ({first!r})") from None
    chunks = sorted(
        (c for c in summary.chunk_indexes if c.message_index_offsets),
        key=lambda c: (c.message_start_time, c.message_end_time),
    )
    located: List[_Located] = []
    for k, chunk in enumerate(chunks):
        start, end = chunk.message_start_time, chunk.message_end_time
        if k > 0 and start <= located[-1][2]:
            raise DatasetError(
                f"{shard}: the chunks of frames {k - 1} and {k} overlap in time "
                f"({located[-1][1]}..{located[-1][2]} ns and {start}..{end} ns); each "
                f"chunk of an episode is one camera frame up to the next"
            )
        located.append((first + k, start, end))
    frames = episode.get("frames")
    if isinstance(frames, int) and frames != len(chunks):
        raise DatasetError(
            f"{shard}: its episode record has {frames} frames, the shard {len(chunks)} chunks"
        )
    return located, {**episode, "shard": shard, "first_sample": first, "frames": len(chunks)}


def _add_shard_samples(
    found: Dict[int, Tuple[str, int, int]],
    located: Sequence[_Located],
    shard: str,
    split: str,
    entry: Mapping[str, Any],
) -> None:
    """Add a shard's chunks to ``found`` (split index -> (shard, start, end)): no sample twice,
    and the samples the manifest lists for the shard."""
    indices: List[int] = []
    for index, start, end in located:
        if index in found:
            other = found[index][0]
            raise DatasetError(
                f"sample {index} of split {split!r} is stored twice: in {other} and {shard}"
            )
        found[index] = (shard, start, end)
        indices.append(index)
    first, count = entry.get("first_sample"), entry.get("samples")
    if isinstance(first, int) and isinstance(count, int):
        if sorted(indices) != list(range(first, first + count)):
            raise DatasetError(
                f"{shard}: the manifest lists samples {first}..{first + count - 1} but the "
                f"shard's chunk indexes hold {len(indices)} samples "
                f"({_describe_range(sorted(indices))})"
            )


def _build_index(
    root: Path,
    split: str,
    split_entry: Mapping[str, Any],
    shards_out: List[str],
    manifest: Mapping[str, Any],
    episodes_out: List[Dict[str, Any]],
) -> List[Tuple[str, int, int]]:
    """Map every sample of the split to (shard path, chunk start, chunk end log time) from the
    shards' chunk indexes; each episode shard's record goes to ``episodes_out``."""
    manifest_path = root / MANIFEST_FILE
    found: Dict[int, Tuple[str, int, int]] = {}
    for entry in split_entry.get("shards", []):
        if entry.get("sha256") is None:
            continue  # listed but not generated yet (interrupted or distributed run)
        path = root / entry["file"]
        if not path.is_file():
            raise DatasetNotFoundError(
                f"shard {path} is listed in {manifest_path} but missing on disk"
            )
        shard = str(path)
        shards_out.append(shard)
        summary, meta = _read_shard_summary(shard)
        _check_shard_belongs(shard, meta, split, entry, manifest)
        assert meta is not None
        episode = _episode_record(shard, meta)
        if episode is None:
            located = _snapshot_chunks(shard, summary)
        else:
            located, listed = _episode_chunks(shard, summary, meta, entry, episode)
            episodes_out.append(listed)
        _add_shard_samples(found, located, shard, split, entry)
    n = len(found)
    if n and (min(found) != 0 or max(found) != n - 1):
        missing = next(i for i in range(max(found) + 1) if i not in found)
        raise DatasetError(
            f"split {split!r} of {root} is not contiguous: {n} samples found but sample {missing} "
            f"is missing (is a shard still unwritten? see 'complete' in {manifest_path})"
        )
    return [found[i] for i in range(n)]


def _describe_range(indices: Sequence[int]) -> str:
    if not indices:
        return "none"
    return f"{indices[0]}..{indices[-1]}"
