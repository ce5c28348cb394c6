"""A patch of numba: read a cached kernel without parsing the LLVM bitcode it is stored with, until (if ever)
another compilation links it in. Applied only by :func:`flow_node.process.defer_kernel_bitcode`, which every
executable's ``main()`` (and the Dask workers' preload) calls; nothing here runs on import.

Why: numba stores a cached kernel as its object code plus the bitcode of a "shared module", the kernel's LLVM
module kept so that a later compilation can inline it (``CPUCodeLibrary._get_module_for_linking``). Reading
the kernel (``CPUCodeLibrary._unserialize``) parses that bitcode every time and walks it for the names of
the symbols the kernel defines (``JitEngine._load_defined_symbols``), which ``get_pointer_to_function``
checks before it asks the execution engine for an address. In a fresh ``flow_estimate`` that is ~70 % of
the time of reading the kernels (docs/engine.md, "Compiled kernels"); the object code alone is what runs.

What the patched read does instead, for a kernel stored as object code in ELF64 little-endian (Linux):
the defined symbols' names come from the object's own symbol table (the same set: ``test_numba_patch``
compares them on the engine's kernels), the bitcode is kept as bytes on the library, and
``_get_module_for_linking`` parses it on first use -- only a compilation that calls an already cached
kernel needs it. Everything else is numba's own code, in numba's own order. Anything else (another object
format, a kernel stored as bitcode, a numba whose code these overrides were not checked against) takes
numba's stock path: the overrides apply only to the numba versions in :data:`CHECKED`, whose functions they
replace were read and are pinned by a hash of their source (``test_numba_patch``).
"""

from __future__ import annotations

import hashlib
import struct
from importlib import metadata
from typing import Any

# numba versions whose CPUCodeLibrary._unserialize / _get_module_for_linking and JitEngine symbol tracking
# the overrides below were written against (the versions requirements.txt and requirements-system-ros.txt
# pin); test_numba_patch checks that the installed one's source still hashes to SOURCE_SHA256.
CHECKED = ("0.61.2", "0.68.1")
SOURCE_SHA256 = "8b8f7b8b5bdd6724be001a120a121f62b0eb11b844e4f6e8295ebb815426703f"
_BITCODE = "_flow_node_shared_bitcode"  # the attribute that holds a library's unparsed shared-module bitcode
_STT_SECTION, _STT_FILE = 3, 4  # ELF symbol types that name no function or variable


def elf_defined_symbols(obj: bytes) -> set[str] | None:
    """Names of the functions and variables an ELF64 little-endian object file defines (its symbol table's
    entries with a section, other than section and file symbols); None for anything else (numba then
    parses the bitcode as usual)."""
    if obj[:4] != b"\x7fELF" or obj[4] != 2 or obj[5] != 1:  # magic, ELFCLASS64, ELFDATA2LSB
        return None
    (shoff,) = struct.unpack_from("<Q", obj, 0x28)
    shentsize, shnum = struct.unpack_from("<HH", obj, 0x3A)
    # section headers: (name, type, flags, addr, offset, size, link, info, addralign, entsize)
    sections = [struct.unpack_from("<IIQQQQIIQQ", obj, shoff + i * shentsize) for i in range(shnum)]
    names: set[str] = set()
    for _, kind, _, _, offset, size, link, _, _, _ in sections:
        if kind != 2:  # SHT_SYMTAB
            continue
        strings = sections[link][4]
        for name, info, _, shndx, _, _ in struct.iter_unpack("<IBBHQQ", obj[offset:offset + size]):
            if name and shndx and (info & 15) not in (_STT_SECTION, _STT_FILE):
                start = strings + name
                names.add(obj[start:obj.index(b"\0", start)].decode())
    return names


def installed_numba() -> str | None:
    """The installed numba's version (from its package metadata: numba is not imported), None without it."""
    try:
        return metadata.version("numba")
    except metadata.PackageNotFoundError:
        return None


def deferred(library: Any) -> bool:
    """Whether ``library`` (a numba code library) was read by the patched read and its bitcode not parsed yet."""
    return _BITCODE in vars(library)


def install() -> bool:
    """Replace numba's cached-kernel read by the deferred one (module docstring); idempotent. Returns whether
    it applies: False without numba or on a numba version not in :data:`CHECKED` (numba's own read stays)."""
    try:
        import numba
        from numba.core import codegen
    except ImportError:
        return False
    if numba.__version__ not in CHECKED:
        return False
    library = codegen.CPUCodeLibrary
    if getattr(library, "_flow_node_patched", False):
        return True
    stock_unserialize, stock_linking = library._unserialize.__func__, library._get_module_for_linking

    def _unserialize(cls: type, codegen_: Any, state: tuple[str, str, Any]) -> Any:
        name, kind, data = state
        symbols = elf_defined_symbols(data[0]) if kind == "object" else None
        if symbols is None:
            return stock_unserialize(cls, codegen_, state)
        object_code, shared_bitcode = data
        self = codegen_.create_library(name)
        assert isinstance(self, cls)
        self.enable_object_caching()
        self._set_compiled_object(object_code)
        setattr(self, _BITCODE, shared_bitcode)  # numba: self._shared_module = ll.parse_bitcode(...)
        self._finalize_final_module()
        codegen_._engine._defined_symbols |= symbols  # numba: _load_defined_symbols(self._shared_module)
        return self

    def _get_module_for_linking(self: Any) -> Any:
        shared_bitcode = self.__dict__.pop(_BITCODE, None)
        if shared_bitcode is not None:
            self._shared_module = codegen.ll.parse_bitcode(shared_bitcode)
        return stock_linking(self)

    library._unserialize = classmethod(_unserialize)
    library._get_module_for_linking = _get_module_for_linking
    library._flow_node_patched = True
    library._flow_node_stock = (stock_unserialize, stock_linking)
    return True


def stock_source_digest() -> str:
    """SHA-256 of the source of the numba functions the overrides replace or rely on, as installed (numba's
    own even after :func:`install`): ``CPUCodeLibrary._unserialize`` and ``_get_module_for_linking``,
    ``JitEngine._load_defined_symbols`` and ``is_symbol_defined``."""
    import inspect

    from numba.core import codegen

    library = codegen.CPUCodeLibrary
    unserialize, linking = getattr(library, "_flow_node_stock", (library._unserialize.__func__,
                                                                 library._get_module_for_linking))
    functions = (unserialize, linking, codegen.JitEngine._load_defined_symbols, codegen.JitEngine.is_symbol_defined)
    return hashlib.sha256("".join(inspect.getsource(f) for f in functions).encode()).hexdigest()
