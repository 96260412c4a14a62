//! The release `motile` binary starts on a bare compute node: it links only the C library,
//! libm, libgcc_s and the loader (CUDA and MPI are loaded at run time or not at all in the
//! default build; chart text comes from a font the binary carries, not from fontconfig).

#[cfg(target_os = "linux")]
#[test]
fn the_binary_links_only_the_c_runtime() {
    let exe = env!("CARGO_BIN_EXE_motile");
    let out = match std::process::Command::new("ldd").arg(exe).output() {
        Ok(o) => o,
        Err(e) => panic!("ldd could not run ({e}); it comes with the C library on Linux"),
    };
    let text = String::from_utf8_lossy(&out.stdout);
    let allowed = ["linux-vdso", "libgcc_s", "libm.", "libc.", "ld-linux"];
    let extra: Vec<&str> = text
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !allowed.iter().any(|a| l.contains(a)))
        .collect();
    assert!(
        extra.is_empty(),
        "{exe} needs libraries a bare node lacks:\n{}",
        extra.join("\n")
    );
}
