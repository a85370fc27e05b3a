"""What crosses the wire: message schemas, key expressions, link faults."""
