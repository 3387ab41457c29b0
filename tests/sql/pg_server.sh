#!/usr/bin/env bash
# Starts / stops a private PostgreSQL 15 for the SQL tests (issue 13, section 3.4): initdb into a
# temporary directory, listening only on a Unix socket inside it (listen_addresses=''), run as an
# unprivileged user (`nobody` when the tests run as root). CTest runs `stop` as a FIXTURES_CLEANUP
# step, so the server is stopped and the directory removed also when a test fails.
#   pg_server.sh start STATEFILE EXT_DIR    (EXT_DIR: build dir holding rayscan.so/.control/.sql)
#   pg_server.sh stop STATEFILE
# STATEFILE receives the data directory; the tests read it to connect (host=<dir> port=5432).
set -euo pipefail
cmd=$1 state=$2
PGBIN=$(pg_config --bindir 2>/dev/null || echo /usr/lib/postgresql/15/bin)
[ -x "$PGBIN/initdb" ] || PGBIN=/usr/lib/postgresql/15/bin
as_user() {
  if [ "$(id -u)" -eq 0 ]; then runuser -u nobody -- "$@"; else "$@"; fi
}
case $cmd in
start)
  ext=$3
  rm -f "$state"
  if [ ! -x "$PGBIN/initdb" ]; then echo "pg_server: PostgreSQL 15 not installed; skipping"; exit 0; fi
  # Install the extension the way `make install` / `cmake --install` would.
  libdir=$(pg_config --pkglibdir) share=$(pg_config --sharedir)/extension
  if [ -w "$libdir" ] && [ -w "$share" ]; then
    install -m 644 "$ext/rayscan.so" "$libdir/rayscan.so"
    install -m 644 "$ext/rayscan.control" "$ext/rayscan--0.1.sql" "$share/"
  elif ! cmp -s "$ext/rayscan.so" "$libdir/rayscan.so"; then
    echo "pg_server: cannot install the extension into $libdir (not writable); skipping"; exit 0
  fi
  dir=$(mktemp -d /tmp/rayscan-pg.XXXXXX)
  [ "$(id -u)" -eq 0 ] && chown nobody "$dir"
  chmod 700 "$dir"
  as_user "$PGBIN/initdb" -D "$dir/data" -U postgres -A trust --no-sync >"$dir/initdb.log" 2>&1 ||
    { cat "$dir/initdb.log"; rm -rf "$dir"; exit 1; }
  as_user "$PGBIN/pg_ctl" -D "$dir/data" -l "$dir/server.log" -w -t 60 \
    -o "-c listen_addresses='' -c unix_socket_directories='$dir' -c port=5432 -c fsync=off" start ||
    { cat "$dir/server.log"; rm -rf "$dir"; exit 1; }
  chmod 755 "$dir"  # the tests (possibly root) connect through the socket in it
  echo "$dir" >"$state"
  echo "pg_server: running in $dir"
  ;;
stop)
  [ -f "$state" ] || exit 0
  dir=$(cat "$state")
  as_user "$PGBIN/pg_ctl" -D "$dir/data" -m immediate -w stop || true
  rm -rf "$dir" "$state"
  echo "pg_server: stopped, $dir removed"
  ;;
esac
