"""The one argument of the fused engine's kernel: every array of a launch in a Taichi argpack
(a kernel takes at most 64 arguments; the engine's functions take the pack as one template
argument). Columns are those of `ddatai.fused.layout`. Importing this module imports Taichi."""


import taichi as ti

I1 = ti.types.ndarray(dtype=ti.i32, ndim=1)
I2 = ti.types.ndarray(dtype=ti.i32, ndim=2)
F1 = ti.types.ndarray(dtype=ti.f64, ndim=1)
F2 = ti.types.ndarray(dtype=ti.f64, ndim=2)

#: name -> Taichi type of every array of a launch (the order of `ddatai.fused.pack.Arrays`)
FIELDS = {
    "mi": I2, "mf": F2, "ccount": I1,                                  # members
    "bint": I2, "bmat": F2, "bst": F2, "bgeo": F2, "bwork": F2,       # blocks
    "rblock": I1, "env": I1,                                           # rows of the systems
    "vnext": I1, "vprev": I1, "vblock": I1, "vjoint": I1,             # vertices
    "vxy": F2, "vxy0": F2, "vnew": F2,
    "cint": I2, "cf": F2, "cvec": F2, "clen": F1,                      # contacts
    "memi": I2, "memf": F2,                                            # contact memory
    "kmat": F1, "xvec": F1,                                            # matrix and vector slabs
    "pint": I2, "pf": F2, "pj": I2, "jf": F2, "gidx": I1,              # points, joints, groups
    "hist": F2, "rec": F2, "frame": F1,                                # records
}

Pack = ti.types.argpack(**FIELDS)
