"""Optimal design of the XYΘ identification poses: criteria, the discrepancy, the plan, the study."""
