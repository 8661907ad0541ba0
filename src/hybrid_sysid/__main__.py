from hybrid_sysid.train import main

main()
