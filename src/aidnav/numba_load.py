"""numba's cache loaded without parsing what a run never uses (issue 29: memory and start-up).

A function cached with ``cache=True`` is stored by numba as its machine code (an ELF object) *and* the
LLVM bitcode of the whole library (the function and everything inlined into it), the latter only for
compiling another function that calls it. numba parses that bitcode into an LLVM module on every load,
only to learn the names of the symbols the library defines; the parsed module then stays in memory. For
the filter engine's kernel that is 1.9 MB of bitcode, about 24 MiB of resident memory and tens of
milliseconds per process, although a command only runs the cached machine code.

:func:`install` makes the bitcode lazy: the defined symbols are read from the object's ELF symbol table
(the same names: the object is compiled from that module), and the bitcode is parsed the first time
numba asks for the module to link it into a new compilation (``_get_module_for_linking``, which also
re-serialises it). Anything unexpected (not an x86-64/ELF64 little-endian object, another numba
internals layout) leaves numba's own path in place. The ``aidnav`` console script installs it before a
command runs (:mod:`aidnav.cli`; ``AIDNAV_NUMBA_LAZY_BITCODE=0`` in the environment keeps numba's own
loader); library users and the tests keep numba as it is unless they call it.
"""

from __future__ import annotations

import struct

_installed = False

_SHT_SYMTAB, _SHN_UNDEF = 2, 0
_ST_TYPES = (0, 1, 2)  # STT_NOTYPE, STT_OBJECT, STT_FUNC (not sections or file names)


def elf_defined_symbols(obj: bytes) -> set[str] | None:
    """Names of the symbols an ELF64 little-endian relocatable object defines (local and global), or
    None when ``obj`` is not such an object."""
    if len(obj) < 64 or obj[:4] != b"\x7fELF" or obj[4] != 2 or obj[5] != 1:
        return None
    (shoff,) = struct.unpack_from("<Q", obj, 0x28)
    shentsize, shnum = struct.unpack_from("<HH", obj, 0x3A)
    if shentsize != 64 or shoff + shnum * 64 > len(obj):
        return None
    # sh_name, sh_type, sh_flags, sh_addr, sh_offset, sh_size, sh_link, sh_info, sh_addralign, sh_entsize
    sections = [struct.unpack_from("<IIQQQQIIQQ", obj, shoff + 64 * i) for i in range(shnum)]
    names: set[str] = set()
    for sh in sections:
        if sh[1] != _SHT_SYMTAB:
            continue
        strings = sections[sh[6]][4]
        for off in range(sh[4], sh[4] + sh[5] - 23, 24):
            st_name, st_info, _, st_shndx = struct.unpack_from("<IBBH", obj, off)
            if st_name and st_shndx != _SHN_UNDEF and st_info & 0xF in _ST_TYPES:
                a = strings + st_name
                names.add(obj[a:obj.index(b"\0", a)].decode())
    return names


def install() -> bool:
    """Make numba's cached libraries load without parsing their bitcode (module doc); returns whether
    the change is in place (idempotent)."""
    global _installed
    if _installed:
        return True
    try:
        import llvmlite.binding as ll
        from numba.core.codegen import CPUCodeLibrary
    except ImportError:  # pragma: no cover - numba is a dependency
        return False
    original = CPUCodeLibrary.__dict__.get("_unserialize")
    linking = CPUCodeLibrary.__dict__.get("_get_module_for_linking")
    if not isinstance(original, classmethod) or linking is None:  # another numba layout: leave it be
        return False
    original = original.__func__

    def _unserialize(cls, codegen, state):
        name, kind, data = state
        names = elf_defined_symbols(data[0]) if kind == "object" else None
        engine = getattr(codegen, "_engine", None)
        if not names or not isinstance(getattr(engine, "_defined_symbols", None), set):
            return original(cls, codegen, state)
        object_code, shared_bitcode = data
        self = codegen.create_library(name)
        self.enable_object_caching()
        self._set_compiled_object(object_code)
        self._aidnav_bitcode = shared_bitcode
        self._finalize_final_module()
        engine._defined_symbols |= names
        return self

    def _get_module_for_linking(self):
        bitcode = self.__dict__.pop("_aidnav_bitcode", None)
        if bitcode is not None and self._shared_module is None:
            self._shared_module = ll.parse_bitcode(bitcode)
        return linking(self)

    CPUCodeLibrary._unserialize = classmethod(_unserialize)
    CPUCodeLibrary._get_module_for_linking = _get_module_for_linking
    _installed = True
    return True
