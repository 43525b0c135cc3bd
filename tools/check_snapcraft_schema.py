#!/usr/bin/env python3
"""Validate snap/snapcraft.yaml against the JSON schema snapcraft 7.x uses for core20.

The schema is kept in the repository (tools/data/snapcraft-core20.json, from snapcraft 7.5.9;
tools/refresh_check_data.py copies it), so the check runs in any clone; without it, it fails.

Usage: check_snapcraft_schema.py SNAPCRAFT_YAML [--schema FILE]
"""
import argparse
import json
import sys
from pathlib import Path

import jsonschema
import yaml


def schema_errors(document, schema):
    validator = jsonschema.Draft4Validator(schema, format_checker=jsonschema.FormatChecker())
    return sorted(validator.iter_errors(document), key=lambda error: list(error.absolute_path))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("snapcraft_yaml", type=Path)
    default_schema = Path(__file__).resolve().parent / "data" / "snapcraft-core20.json"
    parser.add_argument("--schema", type=Path, default=default_schema)
    args = parser.parse_args(argv)

    if not args.schema.is_file():
        print(f"check_snapcraft_schema: no schema at {args.schema} (tools/refresh_check_data.py writes it)",
              file=sys.stderr)
        return 1
    if not args.snapcraft_yaml.is_file():
        print(f"check_snapcraft_schema: no {args.snapcraft_yaml}", file=sys.stderr)
        return 1
    try:
        document = yaml.safe_load(args.snapcraft_yaml.read_text())
        schema = json.loads(args.schema.read_text())
    except (yaml.YAMLError, ValueError) as error:
        print(f"check_snapcraft_schema: cannot read its inputs: {' '.join(str(error).split())}", file=sys.stderr)
        return 1
    errors = schema_errors(document, schema)
    for error in errors:
        where = "/".join(str(part) for part in error.absolute_path) or "(top level)"
        print(f"check_snapcraft_schema: {where}: {error.message}", file=sys.stderr)
    if not errors:
        print(f"check_snapcraft_schema: {args.snapcraft_yaml} is valid")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
