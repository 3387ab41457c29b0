#!/usr/bin/env bash
# The man pages of cmake/man_pages.cmake: each exists, is a help2man page named after its file, and
# renders with groff (the formatter man(1) uses) into a page with NAME, SYNOPSIS and OPTIONS
# sections, the OPTIONS section listing --help.
#   check_man_pages.sh PAGE.1...
set -euo pipefail
fail=0
for page in "$@"; do
  name=$(basename "$page" .1)
  if [ ! -s "$page" ]; then echo "$page: missing or empty (build the rayscan_man_pages target)"; fail=1; continue; fi
  text=$(groff -man -Tutf8 -P-c -P-b -P-u "$page" 2>&1) || { echo "$page: groff fails"; fail=1; continue; }
  bad=0
  for section in NAME SYNOPSIS OPTIONS; do
    grep -q "^$section" <<<"$text" || { echo "$page: no $section section"; bad=1; }
  done
  grep -Eq "^ *$name +- " <<<"$text" || { echo "$page: NAME does not read '$name - ...'"; bad=1; }
  options=$(sed -n '/^OPTIONS/,/^[A-Z]/p' <<<"$text")
  grep -q -- '--help' <<<"$options" || { echo "$page: OPTIONS without --help"; bad=1; }
  if [ $bad -eq 0 ]; then echo "$page: ok ($(wc -l <<<"$text") lines)"; else fail=1; fi
done
exit $fail
