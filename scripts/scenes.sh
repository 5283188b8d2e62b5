# Sourced by the measurement scripts: `scenes` lists the committed scenes
# and the real ones of ../shared/scenes; `scene_name FILE` names a row
# (committed scenes by file name, real ones by their folder's).
scenes=(scenes/*.obj)
for d in ../shared/scenes/*/; do
    f=$(ls "$d" | grep -E '\.(obj|gltf|glb)$' | head -1 || true)
    [ -n "$f" ] && scenes+=("$d$f")
done
scene_name() {
    case "$1" in
        scenes/*) local n; n=$(basename "$1"); echo "${n%.*}" ;;
        *) basename "$(dirname "$1")" ;;
    esac
}
