//! Build script of every package that links MuJoCo (icrflow-physics, icrflow-nodes, icrflow):
//! their binaries and tests find `libmujoco.so.3.17.0` at run time where the build found it,
//! through an rpath. `MUJOCO_DYNAMIC_LINK_DIR` (set in `.cargo/config.toml`: the repository's
//! `.mujoco/lib`) holds links that scripts/setup.sh makes to the library of PyPI's `mujoco`
//! wheel; the rpath is the folder the links resolve to (the wheel's), so a binary does not
//! depend on the clone it was built from.

fn main() {
    println!("cargo::rerun-if-env-changed=MUJOCO_DYNAMIC_LINK_DIR");
    let Some(dir) = std::env::var_os("MUJOCO_DYNAMIC_LINK_DIR") else {
        return;
    };
    let link = std::path::Path::new(&dir).join("libmujoco.so");
    println!("cargo::rerun-if-changed={}", link.display());
    let resolved = link
        .canonicalize()
        .ok()
        .and_then(|l| l.parent().map(std::path::Path::to_path_buf))
        .unwrap_or_else(|| std::path::PathBuf::from(&dir));
    println!("cargo::rustc-link-arg=-Wl,-rpath,{}", resolved.display());
}
