#!/usr/bin/env bash
# Prints the Debian packages that provide the shared libraries the given executables load (for
# the runtime image: install exactly these instead of the -dev packages of the build image).
# Handles merged /usr: a library found as /lib/... may be registered as /usr/lib/... and back.
set -euo pipefail
ldd "$@" | awk '/=> \// { print $3 } /^\s*\/[^ ]+ \(/ { print $1 }' | sort -u |
  while read -r lib; do
    real=$(readlink -f "$lib")
    for p in "$lib" "$real" "/usr$lib" "/usr$real" "${lib#/usr}" "${real#/usr}"; do
      if owner=$(dpkg -S "$p" 2>/dev/null | head -n 1); then
        # "libfoo1:amd64: /path" or "pkg-a, pkg-b: /path": the package names.
        echo "${owner%%: *}" | tr ',' '\n' | sed 's/:.*//; s/ //g'
        break
      fi
    done
  done | sort -u
