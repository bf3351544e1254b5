"""The exceptions the reader raises (re-exported by :mod:`vtdata` and :mod:`vtdata.reader`)."""

from __future__ import annotations


class DatasetError(RuntimeError):
    """A dataset does not follow the vtgen format (missing or inconsistent files or messages).

    The one exception type the reader raises for a damaged, incomplete or foreign dataset: a
    truncated shard, a damaged chunk, a shard from another dataset, a checksum that does not match
    the manifest. Its message names the file and, when reading a sample, the sample.
    """


class DatasetNotFoundError(DatasetError, FileNotFoundError):
    """A file the dataset needs is missing: the folder, ``manifest.json``, a shard or a model.

    Both a :class:`DatasetError` and a :class:`FileNotFoundError`.
    """
