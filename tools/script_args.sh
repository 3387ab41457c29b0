# Sourced by the tools' scripts (build.sh, test.sh, demo.sh, package.sh, sanitize.sh,
# install-deps.sh) for one handling of their arguments: -h / --help prints the script's header
# comment (what it does, its usage line) and exits 0; any other option, or more arguments than
# the script takes, is refused in one line with exit 2, so a typo never becomes a build folder.

# script_args DEFAULT "$@": BUILD is the one optional argument (a build folder) or DEFAULT.
script_args() {
  local default="$1"
  shift
  script_options "$@"
  if [ $# -gt 1 ]; then
    echo "$(basename "$0"): one argument at most (the build folder), got $# (see --help)" >&2
    exit 2
  fi
  BUILD="${1:-$default}"
}

# script_no_args "$@": for a script that takes no argument.
script_no_args() {
  script_options "$@"
  if [ $# -gt 0 ]; then
    echo "$(basename "$0"): takes no argument, got '$1' (see --help)" >&2
    exit 2
  fi
}

# --help, or an option refused; anything else is left to the caller.
script_options() {
  case "${1:-}" in
    -h | --help)
      local self="$0"  # (the callers but install-deps.sh have changed to the repository root)
      [ -f "$self" ] || self="tools/$(basename "$0")"
      sed -n '2,/^[^#]/{/^#/s/^# \{0,1\}//p}' "$self"
      exit 0
      ;;
    -*)
      echo "$(basename "$0"): unknown option '$1' (see --help)" >&2
      exit 2
      ;;
  esac
}
