//! Builds omcl's Embree interop: bindgen over `ffi/omcl_embree.h` (the `rtc*`
//! API and our shim), `cc` for `ffi/omcl_embree.c`, and links `embree3`.
//!
//! Debian 12 ships Embree 3.13 as `libembree-dev` without a pkg-config file,
//! so the library is linked by name; `EMBREE_DIR` points at another install
//! (its `include/` and `lib/`).
//!
//! Also generates the gRPC code of `omcl serve` from `proto/omcl.proto` with
//! tonic-prost-build; `protoc` comes from the `protoc-bin-vendored` crate
//! (a binary inside a crates.io package), so no system protoc is needed
//! (`PROTOC` in the environment overrides it).

use std::env;
use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-changed=ffi/omcl_embree.h");
    println!("cargo:rerun-if-changed=ffi/omcl_embree.c");
    println!("cargo:rerun-if-env-changed=EMBREE_DIR");

    let mut include_dirs = Vec::new();
    if let Ok(dir) = env::var("EMBREE_DIR") {
        let dir = PathBuf::from(dir);
        include_dirs.push(dir.join("include"));
        println!(
            "cargo:rustc-link-search=native={}",
            dir.join("lib").display()
        );
    }
    let header_found = include_dirs
        .iter()
        .chain(
            [
                PathBuf::from("/usr/include"),
                PathBuf::from("/usr/local/include"),
            ]
            .iter(),
        )
        .any(|d| d.join("embree3/rtcore.h").exists());
    if !header_found {
        panic!(
            "embree3/rtcore.h not found: install Embree 3 (`apt-get install libembree-dev`, \
             or run `make deps`), or set EMBREE_DIR to an Embree 3 install"
        );
    }

    let mut c = cc::Build::new();
    c.file("ffi/omcl_embree.c")
        .opt_level(3)
        .flag_if_supported("-std=c11");
    for d in &include_dirs {
        c.include(d);
    }
    c.compile("omcl_embree");
    println!("cargo:rustc-link-lib=dylib=embree3");

    let mut b = bindgen::Builder::default()
        .header("ffi/omcl_embree.h")
        .allowlist_function("rtc.*")
        .allowlist_function("omcl_.*")
        .allowlist_type("RTC.*")
        .allowlist_type("Omcl.*")
        .allowlist_var("RTC_.*")
        .allowlist_var("OMCL_.*")
        .default_enum_style(bindgen::EnumVariation::Rust {
            non_exhaustive: false,
        })
        .layout_tests(false)
        .parse_callbacks(Box::new(bindgen::CargoCallbacks::new()));
    for d in &include_dirs {
        b = b.clang_arg(format!("-I{}", d.display()));
    }
    let bindings = b
        .generate()
        .expect("bindgen could not read ffi/omcl_embree.h (is libclang-dev installed?)");
    let out = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    bindings
        .write_to_file(out.join("embree_bindings.rs"))
        .expect("could not write the Embree bindings into OUT_DIR");

    grpc();
}

/// Server and client code of `proto/omcl.proto` into OUT_DIR.
fn grpc() {
    println!("cargo:rerun-if-changed=proto/omcl.proto");
    println!("cargo:rerun-if-env-changed=PROTOC");
    let mut config = tonic_prost_build::Config::new();
    if env::var_os("PROTOC").is_none() {
        let protoc = protoc_bin_vendored::protoc_bin_path()
            .expect("protoc-bin-vendored has no protoc for this platform: set PROTOC");
        config.protoc_executable(protoc);
    }
    tonic_prost_build::configure()
        .compile_with_config(config, &["proto/omcl.proto"], &["proto"])
        .expect("compiling proto/omcl.proto");
}
