"""Tests (a package, so that test folders named like the product packages never shadow them)."""
