#!/usr/bin/env bash
# Checks the image deploy/container/build.sh saved: runs its entrypoint (read from the image's own
# configuration) on scenarios/golden/small_biplanar.toml and requires `rsasim verify` of the host
# build to find the output VERIFIED.
#
#   deploy/container/check.sh [ARCHIVE]      # default: target/rsasim-<version>.oci.tar
#
# With podman where containers run (`podman run` succeeds), it runs the image there; otherwise
# (podman 4.3 on the project's machines stops at cgroups) it unpacks the image with skopeo (from
# Debian's packages) into a root file system of its own and runs the entrypoint there with chroot,
# with an empty environment but the image's own. Exit 0 only when the output verifies.
set -euo pipefail
cd "$(dirname "$0")/../.."
version=$(sed -n 's/^version = "\(.*\)"/\1/p' Cargo.toml | head -n1)
archive=${1:-target/rsasim-$version.oci.tar}
[[ -f $archive ]] || { echo "check.sh: no image archive $archive (run deploy/container/build.sh)" >&2; exit 2; }
target_dir=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
host="$target_dir/release/rsasim"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# The small scenario and the model it reads, as the container will see them under /data.
mkdir -p "$work/data/models"
cp scenarios/golden/small_biplanar.toml "$work/data/"
cp scenarios/models/femoral_component.glb "$work/data/models/"
if command -v podman >/dev/null && podman run --rm "oci-archive:$archive" --version >/dev/null 2>&1; then
    echo "check.sh: running the image with podman"
    podman run --rm -v "$work/data:/data" "oci-archive:$archive" /data/small_biplanar.toml --out /data/out
    out=$work/data/out
else
    echo "check.sh: podman cannot run containers here; unpacking the image and running it with chroot"
    skopeo copy --quiet "oci-archive:$archive" "oci:$work/layout:rsasim"
    rootfs=$work/rootfs
    mkdir -p "$rootfs"
    # The image's layers in order, and its entrypoint and environment, from its own manifest.
    entry=$(python3 - "$work/layout" "$rootfs" <<'PY'
import json, sys, tarfile, pathlib
layout, rootfs = pathlib.Path(sys.argv[1]), sys.argv[2]
blob = lambda d: layout / "blobs" / d.split(":")[0] / d.split(":")[1]
index = json.loads((layout / "index.json").read_text())
manifest = json.loads(blob(index["manifests"][0]["digest"]).read_text())
for layer in manifest["layers"]:
    with tarfile.open(blob(layer["digest"])) as t:
        # The tar filter (no absolute paths, no links out) where this Python has it (3.11.4+).
        t.extractall(rootfs, **({"filter": "tar"} if hasattr(tarfile, "tar_filter") else {}))
config = json.loads(blob(manifest["config"]["digest"]).read_text())["config"]
print(json.dumps({"entrypoint": config["Entrypoint"], "env": config.get("Env", []), "workdir": config.get("WorkingDir", "/")}))
PY
)
    mkdir -p "$rootfs/data"
    cp -r "$work/data/." "$rootfs/data/"
    mapfile -t entrypoint < <(python3 -c 'import json, sys; [print(a) for a in json.loads(sys.argv[1])["entrypoint"]]' "$entry")
    mapfile -t env < <(python3 -c 'import json, sys; [print(a) for a in json.loads(sys.argv[1])["env"]]' "$entry")
    workdir=$(python3 -c 'import json, sys; print(json.loads(sys.argv[1])["workdir"])' "$entry")
    # chroot starts in /, so the paths given are absolute (the image's working folder is /data).
    echo "check.sh: entrypoint ${entrypoint[*]} (working folder $workdir)"
    chroot=$(command -v chroot)
    env -i "${env[@]}" "$chroot" "$rootfs" "${entrypoint[@]}" /data/small_biplanar.toml --out /data/out
    out=$rootfs/data/out
fi
"$host" verify "$out"
