"""help(dicer) teaches: every public function, class, method and property of
the package has a docstring (pybind11 leaves a bare signature otherwise)."""
import inspect

import dicer
from dicer import _core


def test_every_public_name_has_a_docstring():
    missing = []
    for name in dicer.__all__:
        obj = getattr(dicer, name)
        if not (getattr(obj, "__doc__", None) or "").strip():
            missing.append(name)
    for cname, cls in vars(_core).items():
        if not inspect.isclass(cls) or cname.startswith("_") or issubclass(cls, BaseException):
            continue
        if not (cls.__doc__ or "").strip():
            missing.append(cname)
        for k, v in vars(cls).items():
            if k.startswith("_"):
                continue
            if isinstance(v, property) or inspect.isfunction(v):  # a property, or Python's own function
                text = v.__doc__ or ""
            else:
                # pybind11 writes "signature\n\ndocstring"; the signature
                # alone for an undocumented method.
                parts = (getattr(v, "__doc__", None) or "").split("\n\n", 1)
                text = parts[1] if len(parts) == 2 else ""
            if not text.strip():
                missing.append(f"{cname}.{k}")
    assert missing == []
