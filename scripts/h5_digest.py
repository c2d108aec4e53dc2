#!/usr/bin/python3
"""Content digest of SonicBoom HDF5 files: every dataset's name, dtype, shape and bytes and every
attribute, except the creation time. Two files with the same digest hold the same data.
Usage: /usr/bin/python3 scripts/h5_digest.py FILE.h5 ...  (prints "sha256  FILE" per file)"""
import hashlib
import sys

import h5py
import numpy as np

VOLATILE = {"created_utc"}


def digest(path):
    h = hashlib.sha256()

    def attrs(obj):
        for key in sorted(obj.attrs):
            if key in VOLATILE:
                continue
            h.update(key.encode())
            h.update(repr(obj.attrs[key]).encode())

    def visit(name, obj):
        h.update(name.encode())
        attrs(obj)
        if isinstance(obj, h5py.Dataset):
            data = obj[()]
            h.update(str(obj.dtype).encode())
            h.update(repr(obj.shape).encode())
            h.update(np.ascontiguousarray(data).tobytes() if obj.dtype.kind != "O"
                     else repr(data.tolist()).encode())

    with h5py.File(path, "r") as f:
        attrs(f)
        f.visititems(visit)
    return h.hexdigest()


if __name__ == "__main__":
    for path in sys.argv[1:]:
        print("%s  %s" % (digest(path), path))
