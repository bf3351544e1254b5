"""Put on PYTHONPATH by ``python -m vtdata.bop``: toolkit scripts started in new Python processes
register the same exported dataset (``VTDATA_BOP_DATASET``) as the launcher did."""

import os

if os.environ.get("VTDATA_BOP_DATASET"):
    try:
        from vtdata.bop import register

        register(os.environ["VTDATA_BOP_DATASET"])
    except ImportError:  # not a toolkit process (no bop_toolkit_lib): nothing to register
        pass
