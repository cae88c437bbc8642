"""The core layer: what every other layer builds on, importing none of them (the wire and node
layouts, the datapath's request rules and golden model, errors, progress, outputs, provenance,
the configuration table, where the data files are); docs/architecture.md."""
