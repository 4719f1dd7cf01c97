"""Write MATLAB v7.3 (HDF5) copies of MATLAB v5 files, for usray's v7.3 reader tests.

    python3 mat73_from_v5.py SRC_V5.mat OUT_V73.mat    # the same variables as v7.3
    python3 mat73_from_v5.py --sample OUT_V5.mat         # a v5 file of every class

The v7.3 layout is MATLAB's (MathWorks, "MAT-File Versions"; as hdf5storage and
mat73 read it): a 128-byte text header "MATLAB 7.3 MAT-file" in a 512-byte user
block, then HDF5; each variable a top-level dataset or group with a MATLAB_class
attribute; dimensions reversed (MATLAB (a, b) column-major = HDF5 [b, a]); char as
uint16; complex as a compound of real/imag; empty arrays store their dimensions
with MATLAB_empty = 1; a 1x1 struct is a group of its fields (order in
MATLAB_fields); struct arrays and cells hold object references into #refs#.
"""

import sys

import h5py
import numpy as np
import scipy.io

CLASSES = {
    "float64": "double",
    "float32": "single",
    "int8": "int8",
    "uint8": "uint8",
    "int16": "int16",
    "uint16": "uint16",
    "int32": "int32",
    "uint32": "uint32",
    "int64": "int64",
    "uint64": "uint64",
    "bool": "logical",
    "complex128": "double",
    "complex64": "single",
}


def set_class(obj, name):
    obj.attrs.create("MATLAB_class", np.bytes_(name))


class Writer:
    def __init__(self, h5):
        self.h5 = h5
        self.refs = h5.create_group("#refs#")
        self.count = 0

    def reference(self, value):
        """Write `value` into #refs# and return an object reference to it."""
        self.count += 1
        name = f"r{self.count}"
        self.write(self.refs, name, value)
        return self.refs[name].ref

    def reference_array(self, parent, name, values):
        """A dataset of references to `values` (a MATLAB-shaped object array)."""
        refs = np.empty(values.shape[::-1], dtype=h5py.ref_dtype)
        flat = refs.reshape(-1)
        for i, v in enumerate(values.reshape(-1, order="F")):
            flat[i] = self.reference(v)
        return parent.create_dataset(name, data=refs)

    def write(self, parent, name, v):
        v = np.asarray(v)
        if v.dtype.names:  # struct
            fields = list(v.dtype.names)
            g = parent.create_group(name)
            set_class(g, "struct")
            vlen = h5py.vlen_dtype(np.dtype("S1"))
            names = np.empty(len(fields), dtype=vlen)
            for i, f in enumerate(fields):
                names[i] = np.array(list(f), dtype="S1")
            g.attrs.create("MATLAB_fields", names, dtype=vlen)
            if v.size == 1:
                for f in fields:
                    self.write(g, f, v.reshape(-1)[0][f])
            else:
                for f in fields:
                    column = np.empty(v.shape, dtype=object)
                    for idx in np.ndindex(v.shape):
                        column[idx] = v[idx][f]
                    self.reference_array(g, f, column)
            return
        if v.size == 0:
            d = parent.create_dataset(name, data=np.array(v.shape, dtype=np.uint64))
            cls = {"O": "cell", "U": "char"}.get(v.dtype.kind) or CLASSES[v.dtype.name]
            set_class(d, cls)
            d.attrs.create("MATLAB_empty", np.uint8(1))
            return
        if v.dtype.kind == "O":  # cell
            d = self.reference_array(parent, name, v)
            set_class(d, "cell")
            return
        if v.dtype.kind == "U":  # char, one code unit per element
            codes = np.vectorize(ord, otypes=[np.uint16])(v)
            d = parent.create_dataset(name, data=codes.T)
            set_class(d, "char")
            return
        if v.dtype.kind == "c":
            part = v.real.dtype
            compound = np.dtype([("real", part), ("imag", part)])
            data = np.empty(v.shape, dtype=compound)
            data["real"], data["imag"] = v.real, v.imag
            d = parent.create_dataset(name, data=data.T)
        elif v.dtype == bool:
            d = parent.create_dataset(name, data=v.astype(np.uint8).T)
        else:
            d = parent.create_dataset(name, data=v.T)
        set_class(d, CLASSES[v.dtype.name])


def header():
    text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: usray test fixture HDF5 schema 1.00 ."
    return text.ljust(116, b" ") + b"\0" * 8 + b"\x00\x02" + b"IM"


def v5_to_v73(src, out):
    variables = scipy.io.loadmat(src, chars_as_strings=False, mat_dtype=False)
    # A top-level real array in its MATLAB class, not its storage type (MATLAB
    # stores integer-valued doubles in a smaller type: PWI_disk's RF is int16 data
    # of class double). mat_dtype=True would drop imaginary parts, so only there.
    as_class = scipy.io.loadmat(src, chars_as_strings=False, mat_dtype=True)
    for name, value in variables.items():
        if (
            isinstance(value, np.ndarray)
            and value.dtype.kind in "iuf"
            and as_class[name].dtype.kind in "iuf"
        ):
            variables[name] = as_class[name]
    with h5py.File(out, "w", userblock_size=512) as h5:
        w = Writer(h5)
        for name, value in variables.items():
            if not name.startswith("__"):
                w.write(h5, name, value)
    with open(out, "r+b") as f:
        f.write(header())


def sample_v5(out):
    """A v5 file holding every class the readers map but logical (which
    scipy.io.loadmat returns as uint8, so a copy through it could not keep it)."""
    cell = np.empty((1, 3), dtype=object)
    cell[0, 0] = np.array([[1.5, -2.0]])
    cell[0, 1] = "inner text"
    inner = np.empty((2, 1), dtype=object)
    inner[0, 0] = np.int16([[7, -8, 9]])
    inner[1, 0] = np.zeros((0, 3))
    cell[0, 2] = inner
    points = np.zeros((1, 2), dtype=[("x", object), ("label", object)])
    points[0, 0] = (np.array([[1.0]]), "first")
    points[0, 1] = (np.array([[2.0, 3.0]]), "second")
    scipy.io.savemat(
        out,
        {
            "doubles": np.arange(24, dtype=np.float64).reshape(2, 3, 4, order="F") / 7,
            "singles": np.float32([[0.1, 0.2, 0.3]]),
            "ints": {
                "i8": np.int8([[-128, 127]]),
                "u8": np.uint8([[0, 255]]),
                "i16": np.int16([[-32768, 32767]]),
                "u16": np.uint16([[0, 65535]]),
                "i32": np.int32([[-(2**31), 2**31 - 1]]),
                "u32": np.uint32([[0, 2**32 - 1]]),
                "i64": np.int64([[-(2**53), 2**53]]),
                "u64": np.uint64([[0, 2**53]]),
            },
            "z": np.array([[1 + 2j, -3.5j], [0.25, 4]]),
            "text": np.array(["ab", "cd"]),
            "empty": np.zeros((0, 0)),
            "cells": cell,
            "points": points,
        },
        do_compression=True,
    )


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--sample":
        sample_v5(sys.argv[2])
    elif len(sys.argv) == 3:
        v5_to_v73(sys.argv[1], sys.argv[2])
    else:
        sys.exit(__doc__)
