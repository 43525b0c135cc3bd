#!/bin/bash
# Sourced by roscore_daemon.sh and wait_for_master.sh: questions about the ROS master.
# shellcheck shell=bash

# The master at URI $1 answers (its XML-RPC getPid, within 3 s).
master_answers() {
  timeout 5 python3 -c '
import sys, xmlrpc.client, socket
socket.setdefaulttimeout(3)
try:
    code, _, _ = xmlrpc.client.ServerProxy(sys.argv[1]).getPid("/turtlebot3c_master_check")
except Exception:
    sys.exit(1)
sys.exit(0 if code == 1 else 1)
' "$1" >/dev/null 2>&1
}

# A socket can be bound to host $1 (a name or an address; "" for all of this machine's),
# port $2 (0 for any), as the master binds (SO_REUSEADDR: TIME_WAIT is no obstacle).
can_bind() {
  timeout 5 python3 -c '
import socket, sys
sock = socket.socket()
sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
try:
    sock.bind((socket.gethostbyname(sys.argv[1]), int(sys.argv[2])))
except OSError:
    sys.exit(1)
' "$1" "$2" >/dev/null 2>&1
}

# Nothing on this machine listens on TCP port $1: the master's bind to it would succeed.
port_is_free() {
  can_bind "" "$1"
}

# The host of URI $1 (http://HOST:PORT/ -> HOST).
uri_host() {
  local rest="${1#*://}"
  rest="${rest%%/*}"
  printf '%s' "${rest%:*}"
}

# The port of URI $1 (11311 when it names none).
uri_port() {
  local rest="${1#*://}"
  rest="${rest%%/*}"
  case "$rest" in
    *:*) printf '%s' "${rest##*:}" ;;
    *) printf '11311' ;;
  esac
}

# Host $1 is this machine: localhost, our own name (with .local), or an address of ours
# (one a socket can be bound to).
host_is_here() {
  local this_host
  this_host="$(uname -n)"
  case "$1" in
    localhost | localhost.localdomain | 127.* | "$this_host" | "$this_host.local") return 0 ;;
  esac
  can_bind "$1" 0
}
