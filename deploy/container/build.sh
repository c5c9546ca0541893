#!/usr/bin/env bash
# Builds the container image that the Kubernetes manifests in deploy/k8s/ name, `rsasim:<version>`
# (the version in Cargo.toml), from this checkout, and saves it as an OCI archive.
#
#   deploy/container/build.sh [ARCHIVE]      # default: target/rsasim-<version>.oci.tar
#
# Tools: cargo, and buildah from Debian's packages (`apt-get install buildah`), run as root with
# the vfs storage driver in a private, temporary storage folder (nothing is left in the host's
# container storage). The image holds only the release binary at /usr/local/bin/rsasim and the
# shared libraries it links (as `ldd` lists them, at the same paths), no shell and no package
# manager; its entrypoint is the binary, PATH finds it as `rsasim` (the manifests' command), its
# working folder is /data (the manifests' volume). Load it into a cluster's registry with, e.g.,
# `skopeo copy oci-archive:ARCHIVE docker://REGISTRY/rsasim:<version>`.
# deploy/container/check.sh runs the image's entrypoint on a small scenario and verifies the output.
set -euo pipefail
cd "$(dirname "$0")/../.."
version=$(sed -n 's/^version = "\(.*\)"/\1/p' Cargo.toml | head -n1)
archive=${1:-target/rsasim-$version.oci.tar}
cargo build --release --locked --quiet
target_dir=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')
bin="$target_dir/release/rsasim"
work=$(mktemp -d)
trap 'buildah --root "$work/storage" --runroot "$work/run" rm --all >/dev/null 2>&1 || true; rm -rf "$work"' EXIT
rootfs=$work/rootfs
install -D -m 0755 "$bin" "$rootfs/usr/local/bin/rsasim"
# The binary's shared libraries and the dynamic loader, at the paths the binary asks for.
ldd "$bin" | grep -oE '/[^ ]+' | sort -u | while read -r lib; do
    install -D -m 0755 "$(readlink -f "$lib")" "$rootfs$lib"
done
mkdir -p "$rootfs/data" "$rootfs/tmp"
chmod 1777 "$rootfs/tmp"
b() { buildah --storage-driver vfs --root "$work/storage" --runroot "$work/run" "$@"; }
ctr=$(b from scratch)
b copy "$ctr" "$rootfs/" / >/dev/null
b config \
    --entrypoint '["/usr/local/bin/rsasim"]' \
    --cmd '["--help"]' \
    --env PATH=/usr/local/bin \
    --workingdir /data \
    --label "org.opencontainers.image.title=rsasim" \
    --label "org.opencontainers.image.version=$version" \
    --label "org.opencontainers.image.revision=$(git rev-parse HEAD)" \
    "$ctr"
b commit --quiet "$ctr" "rsasim:$version" >/dev/null
mkdir -p "$(dirname "$archive")"
rm -f "$archive"
b push --quiet "rsasim:$version" "oci-archive:$archive:rsasim:$version"
echo "rsasim:$version -> $archive ($(du -h "$archive" | cut -f1))"
