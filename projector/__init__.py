"""Assembly guides: 1:1 printable PDF sheets and projected images."""
