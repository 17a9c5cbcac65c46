"""The tilt filter's σ on the synthetic fault recordings with known truth
(:mod:`verticality.tilt.evaluation.faults`), 20 recordings (seeds 0–19) of each: the share of
unflagged samples, and of those within σ and 2σ of the true tilt (pooled, and the worst single
recording). ``python benchmarks/sigma_faults.py`` prints the table of docs/tilt.md, "The
uncertainty under faults"."""

from verticality.tilt.evaluation.faults import FAULTS, sigma_honesty_over_seeds


def main() -> None:
    print(f"{'recording':12s} {'unflagged':>9s} {'within σ':>9s} {'within 2σ':>9s} "
          f"{'worst 2σ':>9s} {'max err (unflagged)':>20s} {'median σ':>9s}")
    for fault in FAULTS:
        h = sigma_honesty_over_seeds(fault, range(20))
        print(f"{fault:12s} {100 * h['unflagged']:8.1f}% {100 * h['within_1sigma']:8.1f}% "
              f"{100 * h['within_2sigma']:8.1f}% {100 * h['worst_within_2sigma']:8.1f}% "
              f"{h['max_unflagged_error_deg']:19.2f}° {h['median_sigma_deg']:8.2f}°")


if __name__ == "__main__":
    main()
