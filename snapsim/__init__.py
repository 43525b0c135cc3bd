"""snapsim: a local stand-in for snapd and `snap`, for machines without snapd.

Modules, in the order a snap goes through them:
- layout: where everything lives under the one state root (--root / SNAPSIM_ROOT)
- prime: snapcraft.yaml -> a prime tree with meta/snap.yaml, as snapcraft builds it
- lint: checks a prime tree the way the store's review tools do
- state, config: installed snaps, their configuration, `snap get/set` typing rules
- environment: the environment and argv snapd's snap-exec gives apps and hooks
- contexts, hooks: hook contexts (config transactions, queued service actions), running hooks
- snapctl: snapctl for hooks and apps (`python3 -m snapsim.snapctl`, a small process per call)
- supervisor, services: systemd's part: run daemons, stop sequence, restarts, journal
- snapd: install, refresh, remove, connections
- cli: the `snapsim` command line
"""
