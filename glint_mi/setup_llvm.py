"""`python -m glint_mi.setup_llvm`: install the start-up hook that points Dr.Jit at a usable LLVM (>= 17) in every
start of this Python environment, whatever is imported first. `make` runs it after installing the package."""
from glint_mi._llvm import candidate_libraries, install_pth

if __name__ == "__main__":
    print(f"wrote {install_pth()}; LLVM for Dr.Jit: {(candidate_libraries() or ['none found'])[0]}")
