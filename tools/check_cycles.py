#!/usr/bin/env python3
"""Fails when files of src/ import each other in a cycle.

A file depends on another when it names a path into it (`crate::a::b`,
`super::x`, outside comments and test modules); `mod.rs`, `lib.rs` and
`main.rs` only declare and re-export modules and are left out. The library
(`src/` without `cli/` and `main.rs`) and the binary (`main.rs` and `cli/`)
are two crates, checked apart. Prints each cycle and exits 1 if any.
"""
import glob
import re
import sys


def graph(root, files):
    def modpath(f):
        p = f[len(root) + 1:-3].split("/")
        if p[-1] in ("mod", "lib", "main"):
            p = p[:-1]
        return p

    hub = lambda f: f.endswith(("mod.rs", "lib.rs", "main.rs"))
    bymod = {tuple(modpath(f)): f for f in files}

    # Items a hub re-exports (`pub use sub::{A, B}`) resolve to the file
    # that holds them, so a re-export does not hide a dependency.
    reexports = {}
    for f in files:
        if not hub(f):
            continue
        text = re.sub(r"//[^\n]*", "", open(f, encoding="utf-8").read())
        for m in re.finditer(r"pub use (?:self::)?([\w:]+?)(?:::\{([^}]*)\}|::(\w+));", text):
            names = m.group(2).split(",") if m.group(2) else [m.group(3)]
            for n in names:
                n = n.strip().split(" as ")[-1].strip()
                if n:
                    reexports[(tuple(modpath(f)), n)] = modpath(f) + m.group(1).split("::")

    def resolve(parts):
        for k in range(len(parts), 0, -1):
            f = bymod.get(tuple(parts[:k]))
            if f is None:
                continue
            if hub(f) and k < len(parts):
                target = reexports.get((tuple(parts[:k]), parts[k]))
                if target and target != parts[:k]:
                    return resolve(target + parts[k + 1:])
            return f
        return None

    g = {f: set() for f in files}
    for f in files:
        src = open(f, encoding="utf-8").read()
        src = re.split(r"#\[cfg\(test\)\]\s*mod tests", src)[0]
        src = re.sub(r"//[^\n]*", "", src)
        me = modpath(f)
        for m in re.finditer(r"\b(crate|super)((?:::\w+)+)", src):
            parts = m.group(2).strip(":").split("::")
            full = parts if m.group(1) == "crate" else me[:-1] + parts
            t = resolve(full)
            if t and t != f and not hub(t):
                g[f].add(t)
    return g


def cycles(g):
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]
    sys.setrecursionlimit(100000)

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in g[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            c = []
            while True:
                w = stack.pop()
                on.discard(w)
                c.append(w)
                if w == v:
                    break
            if len(c) > 1:
                out.append(sorted(c))

    for v in g:
        if v not in index:
            visit(v)
    return out


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else "src"
    every = glob.glob(root + "/**/*.rs", recursive=True)
    lib = [f for f in every if not f.startswith(root + "/cli/") and f != root + "/main.rs"]
    binary = [f for f in every if f.startswith(root + "/cli/") or f == root + "/main.rs"]
    found = cycles(graph(root, lib)) + cycles(graph(root, binary))
    for c in found:
        print("import cycle:", " <-> ".join(c))
    if found:
        sys.exit(1)
    print(f"no import cycles among {len(every)} files of {root}/")


if __name__ == "__main__":
    main()
