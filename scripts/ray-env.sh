# Sourced by the Ray scripts (test-ray-build.sh, scale-ray.sh) from the
# project root: `venv`, a virtual environment with the pinned Ray
# (scripts/requirements.txt; VIS5D_RAY_VENV, default target/ray-venv,
# made on first use), and `bin`, the release vis5d, built.
venv=${VIS5D_RAY_VENV:-target/ray-venv}
if [ ! -x "$venv/bin/ray" ]; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet -r scripts/requirements.txt
fi
cargo build --release --quiet --bin vis5d
bin="${CARGO_TARGET_DIR:-target}/release/vis5d"
