"""The XYΘ campaign summary, its figures and its report template."""
