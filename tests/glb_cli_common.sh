# Sourced by the CLI tests that write and validate .glb files: a temporary
# folder removed on exit, check NAME CONDITION (prints ok/FAIL, sets fail=1),
# and the Khronos validator script ($validator), which must be installed.
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0
check() { if ! eval "$2"; then echo "FAIL: $1"; fail=1; else echo "ok: $1"; fi; }
validator="$SYLVA_SOURCE_DIR/tests/gltf_validate.mjs"
[[ -f $SYLVA_SOURCE_DIR/node_modules/gltf-validator/package.json ]] ||
    { echo "FAIL: gltf-validator missing (run scripts/install-deps.sh)"; exit 1; }
