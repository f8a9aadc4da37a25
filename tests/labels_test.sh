#!/usr/bin/env bash
# CTest readme_labels (label unit): the test labels README.md documents are the
# labels the build has. Each documented label must select at least one test
# (`ctest -N -L ^LABEL$`), so `ctest -L LABEL` cannot pass on nothing, and
# every label a test carries must be documented. Labels whose tests this
# configuration does not register (fuzz without -DDMMR_FUZZ=ON; bench and netem
# in sanitizer builds) are named as such and not counted.
# usage: labels_test.sh README CTEST BUILD_DIR [NOT_BUILT_LABEL...]
set -euo pipefail
readme=${1:?usage: labels_test.sh README CTEST BUILD_DIR [NOT_BUILT_LABEL...]}
ctest=${2:?} build=${3:?}
shift 3
not_built=" $* "

# The list after "tests/" in README's layout: (labels: `unit`, `gl`, ...),
# which may wrap.
line=$(tr '\n' ' ' <"$readme" | grep -o '(labels: [^)]*)' | head -n 1 || true)
documented=$(grep -o '`[a-z0-9_-]*`' <<<"$line" | tr -d '`' || true)
if [ -z "$documented" ]; then
  echo "FAIL: $readme: no \"(labels: \`a\`, \`b\`, ...)\" list of test labels"
  exit 1
fi

fail=0
for label in $documented; do
  if [[ $not_built == *" $label "* ]]; then
    echo "not built here: $label (its tests are not registered in this configuration)"
    continue
  fi
  n=$(cd "$build" && "$ctest" -N -L "^$label\$" | sed -n 's/^Total Tests: *//p')
  if [ "${n:-0}" -gt 0 ]; then
    echo "ok:   label $label selects $n tests"
  else
    echo "FAIL: $readme documents label $label, but \`ctest -L $label\` selects no test"
    fail=1
  fi
done

# Labels in use, one per line after "All Labels:".
used=$(cd "$build" && "$ctest" --print-labels | sed -n '/^All Labels:/,$p' | sed 1d | tr -d ' ')
if [ -z "$used" ]; then
  echo "FAIL: ctest --print-labels in $build lists no labels"
  fail=1
fi
for label in $used; do
  if ! grep -qx "$label" <<<"$documented"; then
    echo "FAIL: tests carry label $label, which $readme does not document"
    fail=1
  fi
done
exit $fail
