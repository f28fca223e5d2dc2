"""Checks a native wheel against the Blender platform it is built for; exits 1 naming every failure.

    python scripts/check_wheel.py BLENDER_EXT_PY PLATFORM WHEEL
    python scripts/check_wheel.py --windows-runtime FILE.exe   (scripts/test-windows)
    python scripts/check_wheel.py --imports-from DLL FILE      (names FILE imports from DLL)

PLATFORM is Blender's name (windows-x64, macos-arm64, macos-x64, linux-x64). The wheel must be
abi3 for Python 3.11+, its platform tag must map to PLATFORM under Blender's own rule
(`blender_platforms_from_wheel_platform` in blender_ext.py, which `--split-platforms` uses to
pick each zip's wheels), and its extension module must be a binary for that platform that
exports `PyInit_shapesmith_native` and needs only libraries every such machine has:

- Windows: a PE32+ x86-64 DLL importing only `python3.dll` (the stable ABI, not
  `python311.dll`) and system DLLs; the MinGW runtime DLLs only when the wheel carries them
  beside the `.pyd` (Python adds the module's own directory to the DLL search path).
- macOS: a Mach-O dylib of the right CPU, linking only libraries under /usr/lib or /System
  and loading on macOS 11.0 (Blender 4.2's minimum on Apple silicon).
- Linux: an ELF x86-64 shared object (auditwheel checks its libraries, in scripts/build).

The binary formats are read here with `struct` (PE/COFF: Microsoft's "PE Format" spec;
Mach-O: <mach-o/loader.h>), so the check needs no tool that apt or PyPI lacks.
"""

import importlib.util
import io
import struct
import sys
import zipfile

MODULE = "shapesmith_native"
INIT = "PyInit_" + MODULE
# maturin puts the extension module inside a package of the same name, beside its __init__.py.
PACKAGE = MODULE + "/"

# DLLs that ship with every Windows 10/11 (Blender 4.2's minimum is Windows 8.1), which the Rust
# standard library and the MinGW C runtime import. The api-ms-win-* names are API sets.
WINDOWS_SYSTEM_DLLS = {
    "kernel32.dll", "ntdll.dll", "msvcrt.dll", "advapi32.dll", "ws2_32.dll", "userenv.dll",
    "bcrypt.dll", "bcryptprimitives.dll", "shell32.dll", "ole32.dll", "oleaut32.dll", "user32.dll",
    "api-ms-win-core-synch-l1-2-0.dll", "api-ms-win-core-winrt-error-l1-1-0.dll",
}
MINGW_RUNTIME_DLLS = {"libstdc++-6.dll", "libgcc_s_seh-1.dll", "libwinpthread-1.dll"}
MACOS_MIN_VERSION = (11, 0)


def fail_list():
    failures = []
    return failures, failures.append


# ---------------------------------------------------------------- PE (Windows)

def read_pe(data):
    """(machine, is_dll, is_pe32_plus, {imported DLL: names}, exported names) of a PE image."""
    if data[:2] != b"MZ":
        raise ValueError("not a PE image (no MZ header)")
    pe = struct.unpack_from("<I", data, 0x3C)[0]
    if data[pe:pe + 4] != b"PE\0\0":
        raise ValueError("not a PE image (no PE signature)")
    machine, n_sections, _, _, _, opt_size, characteristics = struct.unpack_from("<HHIIIHH", data, pe + 4)
    opt = pe + 24
    magic = struct.unpack_from("<H", data, opt)[0]
    plus = magic == 0x20B
    dirs = opt + (112 if plus else 96)
    n_dirs = struct.unpack_from("<I", data, dirs - 4)[0]
    directory = [struct.unpack_from("<II", data, dirs + 8 * i) for i in range(min(n_dirs, 16))]
    sections = []
    for i in range(n_sections):
        s = opt + opt_size + 40 * i
        vsize, vaddr, rsize, raddr = struct.unpack_from("<IIII", data, s + 8)
        sections.append((vaddr, max(vsize, rsize), raddr))

    def offset(rva):
        for vaddr, size, raddr in sections:
            if vaddr <= rva < vaddr + size:
                return rva - vaddr + raddr
        raise ValueError(f"RVA {rva:#x} outside every section")

    def cstring(rva):
        start = offset(rva)
        return data[start:data.index(b"\0", start)].decode("ascii")

    imports = {}  # DLL name -> names of the functions and data imported from it
    rva, size = directory[1] if len(directory) > 1 else (0, 0)
    if rva:
        at = offset(rva)
        while True:
            lookup, _, _, name, thunk = struct.unpack_from("<IIIII", data, at)
            if not (lookup or name or thunk):
                break
            functions = imports.setdefault(cstring(name), [])
            entry = offset(lookup or thunk)
            while (value := struct.unpack_from("<Q" if plus else "<I", data, entry)[0]) != 0:
                if not value >> (63 if plus else 31):  # not imported by ordinal
                    functions.append(cstring((value & 0x7FFFFFFF) + 2))  # skip the 2-byte hint
                entry += 8 if plus else 4
            at += 20
    exports = []
    rva, size = directory[0] if directory else (0, 0)
    if rva:
        at = offset(rva)
        n_names, _, names_rva = struct.unpack_from("<III", data, at + 24)  # NumberOfNames, AddressOfFunctions, AddressOfNames
        for i in range(n_names):
            exports.append(cstring(struct.unpack_from("<I", data, offset(names_rva) + 4 * i)[0]))
    return machine, bool(characteristics & 0x2000), plus, imports, exports


def check_windows(wheel, names, fail):
    pyd = [n for n in names if n.endswith(".pyd")]
    if pyd != [f"{PACKAGE}{MODULE}.pyd"]:
        fail(f"expected one {PACKAGE}{MODULE}.pyd (abi3 name), found {pyd}")
        return
    machine, is_dll, plus, imports, exports = read_pe(wheel.read(pyd[0]))
    if machine != 0x8664 or not plus:
        fail(f"{pyd[0]} is not PE32+ x86-64 (machine {machine:#x}, PE32+ {plus})")
    if not is_dll:
        fail(f"{pyd[0]} is not a DLL")
    if INIT not in exports:
        fail(f"{pyd[0]} does not export {INIT} (exports {exports[:5]})")
    beside = {n[len(PACKAGE):]: n for n in names if n.startswith(PACKAGE) and n.lower().endswith(".dll")}
    carried = {name.lower() for name in beside}
    allowed = WINDOWS_SYSTEM_DLLS | {"python3.dll"} | (MINGW_RUNTIME_DLLS & carried)
    needed = {name.lower() for name in imports}
    if "python3.dll" not in needed:
        fail(f"{pyd[0]} does not import python3.dll (abi3), imports {sorted(needed)}")
    if needed - allowed:
        fail(f"{pyd[0]} needs {sorted(needed - allowed)}, which Windows does not have and the wheel does not carry")
    for name, path in sorted(beside.items()):
        _, _, _, dll_imports, _ = read_pe(wheel.read(path))
        dll = name
        extra = {n.lower() for n in dll_imports} - allowed
        if extra:
            fail(f"{dll} needs {sorted(extra)}")
    return f"PE32+ x86-64 DLL, exports {INIT}, imports {', '.join(sorted(needed))}"


# ---------------------------------------------------------------- Mach-O (macOS)

CPU = {"macos-arm64": 0x0100000C, "macos-x64": 0x01000007}
LC_REQ_DYLD = 0x80000000
LC_SYMTAB, LC_LOAD_DYLIB, LC_ID_DYLIB, LC_LOAD_WEAK_DYLIB = 0x2, 0xC, 0xD, 0x18 | LC_REQ_DYLD
LC_REEXPORT_DYLIB, LC_DYLD_INFO, LC_DYLD_INFO_ONLY = 0x1F | LC_REQ_DYLD, 0x22, 0x22 | LC_REQ_DYLD
LC_VERSION_MIN_MACOSX, LC_BUILD_VERSION, LC_DYLD_EXPORTS_TRIE = 0x24, 0x32, 0x33 | LC_REQ_DYLD
MH_DYLIB, MH_BUNDLE = 6, 8


def uleb(data, at):
    value = shift = 0
    while True:
        byte = data[at]
        at += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if byte < 0x80:
            return value, at


def trie_exports(data, start):
    """The names in a dyld export trie (what dyld looks symbols up in)."""
    names, stack = [], [(0, "")]
    while stack:
        node, prefix = stack.pop()
        at = start + node
        terminal, at = uleb(data, at)
        if terminal:
            names.append(prefix)
        at += terminal
        children = data[at]
        at += 1
        for _ in range(children):
            end = data.index(b"\0", at)
            label = data[at:end].decode("utf-8")
            child, at = uleb(data, end + 1)
            stack.append((child, prefix + label))
    return names


def read_macho(data):
    """(cputype, filetype, linked dylibs, minimum macOS, exported names) of a 64-bit Mach-O."""
    magic, cputype, _, filetype, ncmds, _, _, _ = struct.unpack_from("<IiiIIIII", data, 0)
    if magic != 0xFEEDFACF:
        raise ValueError(f"not a 64-bit little-endian Mach-O (magic {magic:#x})")
    at, dylibs, minos, exports = 32, [], None, []
    for _ in range(ncmds):
        cmd, size = struct.unpack_from("<II", data, at)
        if cmd in (LC_LOAD_DYLIB, LC_LOAD_WEAK_DYLIB, LC_REEXPORT_DYLIB):
            name_at = struct.unpack_from("<I", data, at + 8)[0]
            dylibs.append(data[at + name_at:data.index(b"\0", at + name_at)].decode())
        elif cmd == LC_BUILD_VERSION:
            platform, version = struct.unpack_from("<II", data, at + 8)
            if platform == 1:  # PLATFORM_MACOS
                minos = (version >> 16, (version >> 8) & 0xFF)
        elif cmd == LC_VERSION_MIN_MACOSX:
            version = struct.unpack_from("<I", data, at + 8)[0]
            minos = (version >> 16, (version >> 8) & 0xFF)
        elif cmd in (LC_DYLD_INFO, LC_DYLD_INFO_ONLY):
            off, size_ = struct.unpack_from("<II", data, at + 40)
            exports += trie_exports(data, off) if size_ else []
        elif cmd == LC_DYLD_EXPORTS_TRIE:
            off, size_ = struct.unpack_from("<II", data, at + 8)
            exports += trie_exports(data, off)
        at += size
    return cputype, filetype, dylibs, minos, exports


def check_macos(wheel, names, platform, fail):
    sos = [n for n in names if n.endswith(".so") or n.endswith(".dylib")]
    if sos != [f"{PACKAGE}{MODULE}.abi3.so"]:
        fail(f"expected one {PACKAGE}{MODULE}.abi3.so, found {sos}")
        return
    cputype, filetype, dylibs, minos, exports = read_macho(wheel.read(sos[0]))
    if cputype != CPU[platform]:
        fail(f"{sos[0]} is for CPU {cputype:#x}, not {platform} ({CPU[platform]:#x})")
    if filetype not in (MH_DYLIB, MH_BUNDLE):
        fail(f"{sos[0]} is Mach-O file type {filetype}, not a dylib or bundle")
    if "_" + INIT not in exports:
        fail(f"{sos[0]} does not export {INIT}")
    foreign = [d for d in dylibs if not d.startswith(("/usr/lib/", "/System/"))]
    if foreign:
        fail(f"{sos[0]} links libraries macOS does not have: {foreign}")
    if minos is None or minos > MACOS_MIN_VERSION:
        fail(f"{sos[0]} needs macOS {minos}, newer than {MACOS_MIN_VERSION}")
    arch = {"macos-arm64": "arm64", "macos-x64": "x86-64"}[platform]
    return (f"Mach-O {arch}, exports {INIT}, macOS >= {minos[0]}.{minos[1]}, "
            f"links {', '.join(d.rsplit('/', 1)[-1] for d in dylibs)}")


# ---------------------------------------------------------------- ELF (Linux)

def check_linux(wheel, names, fail):
    sos = [n for n in names if n.endswith(".so")]
    if sos != [f"{PACKAGE}{MODULE}.abi3.so"]:
        fail(f"expected one {PACKAGE}{MODULE}.abi3.so, found {sos}")
        return
    data = wheel.read(sos[0])
    if data[:4] != b"\x7fELF" or data[4] != 2 or struct.unpack_from("<H", data, 18)[0] != 62:
        fail(f"{sos[0]} is not an ELF64 x86-64 object")
    elif struct.unpack_from("<H", data, 16)[0] != 3:
        fail(f"{sos[0]} is not a shared object")
    elif INIT.encode() + b"\0" not in data:
        fail(f"{sos[0]} has no {INIT} symbol")
    return f"ELF64 x86-64 shared object with {INIT} (libraries: auditwheel)"


# ---------------------------------------------------------------- the wheel

def blender_platforms(blender_ext_py, wheel_platform):
    spec = importlib.util.spec_from_file_location("blender_ext", blender_ext_py)
    blender_ext = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(blender_ext)
    return blender_ext.blender_platforms_from_wheel_platform(wheel_platform)


def check(blender_ext_py, platform, path):
    failures, fail = fail_list()
    filename = path.rsplit("/", 1)[-1]
    parts = filename[:-len(".whl")].split("-")
    if len(parts) != 5 or parts[0] != MODULE or parts[2:4] != ["cp311", "abi3"]:
        fail(f"{filename} is not a {MODULE} cp311-abi3 wheel")
        return failures, None
    mapped = blender_platforms(blender_ext_py, parts[4])
    if mapped != [platform]:
        fail(f"its platform tag {parts[4]} means {mapped} to Blender, not [{platform!r}]")
    with zipfile.ZipFile(path) as wheel:
        names = wheel.namelist()
        tags = [line.split(": ", 1)[1] for line in io.TextIOWrapper(wheel.open(
            next(n for n in names if n.endswith(".dist-info/WHEEL")))).read().splitlines()
            if line.startswith("Tag: ")]
        if tags != ["-".join(parts[2:])]:
            fail(f"WHEEL metadata tags {tags} do not match the file name")
        try:
            if platform == "windows-x64":
                summary = check_windows(wheel, names, fail)
            elif platform.startswith("macos-"):
                summary = check_macos(wheel, names, platform, fail)
            elif platform == "linux-x64":
                summary = check_linux(wheel, names, fail)
            else:
                fail(f"unknown platform {platform}")
                summary = None
        except (ValueError, struct.error, IndexError) as error:
            fail(f"unreadable binary: {error}")
            summary = None
    return failures, summary


def check_windows_runtime(path):
    """A Windows test executable linked like the wheel needs no MinGW runtime DLL either."""
    failures, fail = fail_list()
    with open(path, "rb") as binary:
        machine, _, plus, imports, _ = read_pe(binary.read())
    if machine != 0x8664 or not plus:
        fail(f"not PE32+ x86-64 (machine {machine:#x})")
    needed = {name.lower() for name in imports}
    if needed - WINDOWS_SYSTEM_DLLS:
        fail(f"needs {sorted(needed - WINDOWS_SYSTEM_DLLS)}, not linked as the wheel is")
    return failures, f"PE32+ x86-64, imports {', '.join(sorted(needed))}"


def main(argv):
    if len(argv) == 3 and argv[0] == "--imports-from":
        with open(argv[2], "rb") as binary:
            imports = read_pe(binary.read())[3]
        print("\n".join(next((v for k, v in imports.items() if k.lower() == argv[1].lower()), [])))
        return 0
    if len(argv) == 2 and argv[0] == "--windows-runtime":
        failures, summary = check_windows_runtime(argv[1])
        argv = ["windows-x64", argv[1]]
    elif len(argv) == 3:
        failures, summary = check(*argv)
        argv = argv[1:]
    else:
        print("usage: check_wheel.py BLENDER_EXT_PY PLATFORM WHEEL | --windows-runtime FILE.exe", file=sys.stderr)
        return 2
    name = argv[1].rsplit("/", 1)[-1]
    if failures:
        for failure in failures:
            print(f"check_wheel: {argv[0]}: {name}: {failure}", file=sys.stderr)
        return 1
    print(f"{argv[0]}: {name}: {summary}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
