//! Give the shared library a SONAME so that C/C++/Fortran programs link
//! against `libhocurve.so.0` (the ABI major version) rather than the bare name.

fn main() {
    let major = env!("CARGO_PKG_VERSION_MAJOR");
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("linux") {
        println!("cargo:rustc-cdylib-link-arg=-Wl,-soname,libhocurve.so.{major}");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
