# Sourced by the peer scripts with ROOT set to the repository: builds the release CLI
# from the repository's directory, because cargo reads `.cargo/config.toml` (the
# x86-64-v3 flags) from the current directory, not from `--manifest-path`'s.
(cd "$ROOT" && cargo build --release -q -p gharial-cli) >&2
