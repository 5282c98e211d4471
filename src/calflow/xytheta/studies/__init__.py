"""The Monte-Carlo study of the XYΘ identification: points, aggregation, page, CLI."""
