#!/usr/bin/env bash
# Fails (listing the files) if any C++ source differs from what .clang-format prescribes.
set -euo pipefail
cd "$(dirname "$0")/.."
mapfile -t files < <(find include src apps tests bench examples python fuzz -type f \
  \( -name '*.cpp' -o -name '*.hpp' -o -name '*.h' -o -name '*.cc' \) 2>/dev/null | sort)
bad=()
for f in "${files[@]}"; do
  if ! clang-format --dry-run -Werror "$f" >/dev/null 2>&1; then bad+=("$f"); fi
done
if [ ${#bad[@]} -gt 0 ]; then
  echo "check-format: ${#bad[@]} of ${#files[@]} files are not clang-formatted:" >&2
  printf '  %s\n' "${bad[@]}" >&2
  echo "fix with: clang-format -i <file>" >&2
  exit 1
fi
echo "check-format: ${#files[@]} files clean"
